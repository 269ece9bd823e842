"""Joint calibration: one yarn, several specimens (issue 16).

Specimens knitted from one yarn share everything that is the yarn's: the
bending stiffness B, the compact diameter d, the in-plane width w (the
width with which neighbouring loops jam, d for a round yarn), the friction
ratio m and the parameters of the effects (:mod:`knitsim.cell.effects`).
What differs from specimen to specimen is the knit: the loop length L and the
spacings W0, C0, each known within its measurement uncertainty, and the
friction state the knit was left in, phi0.  :func:`calibrate_joint` fits all of
them at once by weighted least squares (:func:`scipy.optimize.least_squares`,
trust region reflective, bounds):

- rows: each specimen's force at its rows, ``(model - measured) / sd``
  (:mod:`knitsim.calibration.specimen`); the model's total force is its
  force per wale times width / W0 (the wales across the specimen).  With
  ``JointSetup.objective = "band"`` a banded row is instead the signed root of
  ``-2 ln`` of the band likelihood (the band as a box, read with the force
  accuracy's Gaussian, a Cauchy tail far outside:
  :meth:`knitsim.calibration.specimen.SpecimenData.band_residuals`), refined from
  each mid-line solution;
- priors: each fitted L, W0, C0 adds the row ``ln(value / stated) / u``, u its
  relative uncertainty (a Gaussian prior in the log: the fit may move the
  geometry as far as the measurement allows, and pays for it);
- variables: ln B; d; w as a fraction of its range [max(d, low), min(high,
  W0/4)) (W0 the narrowest specimen's, 0.999 W0/4: loops jammed at rest
  otherwise); m; the effects' variables (:data:`knitsim.diagnosis.effects.EFFECT_SPECS`);
  per specimen phi0 as a fraction of phimax = atan(m) (section 3.3.1), and
  ln(L, W0, C0 / stated).

Every evaluation is one batched launch (:func:`knitsim.cell.batch.run_batch`)
of every specimen's cell and its finite-difference neighbours (the shared
variables and its own), on one program that passes through every row (the
specimens' rows are one uniform grid).  Starts: the setup's own point and a
Latin hypercube over the variables (seeded), screened in one launch; the best
are refined.

Uncertainty: ``cov = max(s^2, 1) (J^T W J)^-1`` with J the Jacobian of the weighted
rows and priors in the reported variables (B, d, w in mm, m, effect
variables, phi0 in rad, L, W0, C0 in mm), computed at the solution (its steps taken in the fit's own variables,
phi0 a fraction of the cone atan(m), and carried to the reported ones by the chain rule; a step that makes a cell
inadmissible or a row fail is no derivative: :func:`_covariance`), and
``s^2 = chi^2 / (n - k)`` (1 when the sds are right and the model fits): scaled up where the rows scatter
more than their sds, never down (a band's half-width is the scatter between tests, not of the mid-line's rows,
and the priors' sds are stated: s^2 = 0.002 on a band's mid-line had put the yarn 10 standard errors off).  W
weighs a specimen's rows by (1 - rho) / (1 + rho), rho >= 0 the lag-1 autocorrelation of its residuals (an
effective number of independent rows; the mid-line objective: :func:`_row_information`): rows whose errors run
from one to the next carry less than one reading each (AR(1) noise of 0.8 put 6 of 10 fits' yarn beyond 2 of
their standard errors); priors weigh 1.  Correlations from it.  A variable within 0.1 % of its range of a bound is
flagged, with what that bound means; one whose standard error is not finite or
larger than half its range is flagged not identified (:func:`identification_rule`).  Where another refined start
fits as well (chi2 within 3.84 max(s^2, 1) of the best) at a value beyond 3 of its standard errors, the curvature at the
best describes one minimum of several: the standard error is widened to that distance / 1.96, and the estimate is
flagged not identified unless the distance is within a knit's stated sd (:func:`rival_rule`).  So is the best point
with one variable moved 4 standard errors, the others held, where it fits as well (:func:`_profile_probes`: the
refined starts may all fall into one valley).
:attr:`JointResult.flags` lists these, the optimiser's failure (its message),
cells that did not solve, and specimens that do not look like one yarn: a result with a flag is not a
calibration to use.

One yarn? (:func:`_one_yarn_check`, :class:`OneYarnCheck`): a knit's geometry, free within its priors, can
absorb a yarn that differs from specimen to specimen (a specimen of B x 2.5 was fitted with
chi2 / (n - k) = 0.51 and no flag).  So, after a converged fit of two specimens or more, each specimen is
refitted alone with every shared variable its own, from the joint solution (its knit, phi0 and priors as
before; checkpointed like the fit): the drop of chi2 against the variables added, read as an F test (Chow's
test) against the residual variance of the fits with a yarn each, is flagged where p < :data:`ONE_YARN_P`.

The files' zero (``JointSetup.zero``; the scene's ``calibration.zero``, ``"absolute"`` by default): the
model's rest state (C = C0, W = W0, phi0) carries a force (0.0216 N per wale for Dusserre's E-glass at
phi0 = 0: a knit held by its friction, a jammed knit's compacted crossings), but a real knit at rest in
the grips carries about 0 N, and a lab usually zeroes its load cell with the specimen mounted: the file's
0 N is then the model's rest state.  Three modes (:data:`ZERO_MODES`):

- ``"absolute"``: the files' zero is the model's 0 N; each row is fitted as the model's force.  A check
  (:data:`ZERO_CHECK_SD`, :data:`ZERO_CHECK_SHARE`) flags a specimen whose file reads, at rest (its first
  readings, :func:`knitsim.calibration.specimen.rest_reading`), more than 5 noise sd and more than 5 % of
  its peak below the fitted model's force at grip strain 0: a file tared with the knit mounted, fitted as
  absolute, moves m by tens of standard errors (a probe: m 0.103 +- 0.002 against the true 0.20) and
  reads one yarn as two.  The reading at rest is no row of the fit: it is flagged only where it costs more
  than ZERO_CHECK_SD^2 as one more row (a refit with it, :func:`_zero_costs`), else noted as a zero that
  cannot be checked (few rows, rows from past the knit's first slide, a knit free within its priors).
- ``"tared"``: the file's zero is the model's state at grip strain 0 (its rest state): each row is fitted
  as the model's force less the model's rest force, from the same simulation (the batch's rest state).  No
  parameter is added; the report gives the force subtracted (:attr:`SpecimenFit.tare_N`).  Refused with a
  pretension: the pretensioned start would be read off the fit's first increment, too coarse where the
  knit stiffens inside it.
- ``"fitted"``: a force offset per specimen, projected out analytically (variable projection) by the
  law of ``knitsim diagnose``, :func:`knitsim.diagnosis.calibrate.offset_of`: the weighted least-squares
  offset of the specimen's rows (weights 1 / sd; rows after a failed increment left out of it), in the
  units of its force column (total N, or N per wale).  Under the band objective the offset is the
  mid-line's (the same weighted mean), applied to the force before the band likelihood.  Each offset
  counts as a fitted parameter (k = variables + specimens) wherever degrees of freedom are counted; the
  covariance of the other variables, from the Jacobian of the projected rows, is already the one marginal
  over the offsets.  An offset larger than :data:`OFFSET_NOTE_SHARE` of a specimen's peak measured force
  is noted (:attr:`JointResult.notes`), not flagged.  The price: a free offset takes away the rest level,
  which is what identifies phi0 and m in a monotonic pull (a probe: B 0.29 +- 0.042, m 0.135 +- 0.094,
  phi0 not identified, on files whose zero was right).

The tare of a load-cell zero below zero (:mod:`knitsim.calibration.specimen`) is data cleaning before the
fit, in every mode.

Before any solve (:func:`check_setup`, which the calibration scene runs when it is
read): the variables, bounds and priors, and every specimen's strains against the
reach of its knit in the loosest case the fit allows (:func:`reachable_strain` at
L's upper and C0's lower bound, through the largest pretension): a strain column in
per cent is refused, naming the file, row, column and value.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import qmc

from ..cell.batch import run_batch
from ..cell.domain import rest_force_per_wale
from ..cell.history import STATUS_NAMES, STATUS_OK
from ..cell.load_program import LoadProgram, monotonic, pretensioned
from ..cell.material import CellParams
from ..cell.stages import M_MAX, M_TOO_LARGE
from ..diagnosis.calibrate import offset_of
from ..diagnosis.effects import BASELINE_VARIABLES, EFFECT_SPECS, build_params, check_effects
from ..diagnosis.measured import MeasuredCurve, program_for_curve, reachable_strain
from ..errors import KnitsimInputError
from ..friction.identification import covariance
from .specimen import GEOMETRY, SpecimenData, check_reach, pretension_strain, refuse_repeated_tests

#: yarn variables that may be shared (besides the effects' own)
YARN_VARIABLES = ("B", "d", "in_plane_width", "m")
#: variables that may be fitted per specimen
SPECIMEN_VARIABLES = ("phi0",) + GEOMETRY + ("pretension",)
#: default range of a fitted pretension strain (the knit's strain at grip strain 0)
PRETENSION_RANGE = (0.0, 0.05)
#: units of the reported variables
UNITS = {"B": "N mm^2", "d": "mm", "in_plane_width": "mm", "m": "-", "phi0": "rad", "L": "mm", "W0": "mm",
         "C0": "mm", "pretension": "-"}
#: a variable this close to a bound (share of its range) is flagged
BOUND_TOL = 1e-3
#: a parameter whose standard error exceeds this share of its range (high - low) is not identified
NOT_IDENTIFIED_SHARE = 0.5
#: a refined start whose chi2 lies within this many s^2 (the covariance's factor, max(s^2, 1)) of the best fits as well (chi^2 with 1 dof, 95 %): the
#: profile of each variable reaches its values (:func:`rival_rule`)
RIVAL_DCHI2 = 3.84
#: ... and a value of such a start further than this many standard errors from the best shows the standard error
#: (the curvature at the best) understates what the rows leave open
RIVAL_SE = 3.0
#: the best point is probed this many standard errors out on either side of each variable, the others held
#: (:func:`_profile_probes`): beyond RIVAL_SE, where the curvature says it costs 16 s^2 or more
PROBE_SE = 4.0
#: residual of a row whose cell failed (not ok), times max(1, |target| / sd)
FAIL_RESIDUAL = 30.0
#: the one-yarn check (:func:`one_yarn_check`) flags a p-value below this: the chance that one yarn's
#: specimens, fitted as well as the model fits them, are flagged by noise alone
ONE_YARN_P = 1e-3
#: chi2 / (n - k) above which the fit is flagged as not within the curves' noise: the residuals' rms is then
#: over twice the noise the rows are weighted by (stated noise_N, else estimated), beyond what a wrong noise
#: estimate of a few tens of per cent or a few outlying rows give
POOR_FIT_S2 = 4.0
#: ... and the residuals run in long waves (a curve the model does not make), not row to row (noise larger than
#: stated, which the covariance's factor s2 already answers): a specimen's lag-1 autocorrelation of its weighted
#: residuals above this (white noise: 0 +- 1/sqrt(rows); a systematic misfit: near 1)
POOR_FIT_AUTOCORRELATION = 0.5
#: a fitted force offset larger than this share of the specimen's peak measured force is noted (JointResult.notes)
OFFSET_NOTE_SHARE = 0.05
#: ... and beyond this many of its standard errors
OFFSET_NOTE_SE = 2.0
#: the zero check of zero = "absolute" (JointResult.flags): a specimen's file reading at rest more than this many
#: noise sd, and more than ZERO_CHECK_SHARE of its peak measured force, below the fitted model's force at grip
#: strain 0 is flagged (a load cell zeroed with the knit mounted)
ZERO_CHECK_SD = 5.0
ZERO_CHECK_SHARE = 0.05
#: a specimen whose largest reading per wale is below this many B / L^2 of its fitted yarn and knit (the force that
#: bends the yarn over its loop length) is flagged as a force in another unit (_force_scale_flag).  Real knits
#: pulled through a test carry far more: the Do 2020 and Singal 2024 curves 31 to 3800 B / L^2 at any B their
#: fits reached (their calibration 1900 and 2100; Singal's 24 runs 1600 to 10900 at the authors' B), Dusserre's
#: E-glass model curves to strain 0.5 about 60; the same in kN read as N, 0.06 to 4 (the fit leaves B or the
#: knit where the model carries almost nothing: a blind probe's kN file fitted within its noise, no flag)
BENDING_SCALE_SHARE = 10.0


def residual_autocorrelation(r: np.ndarray | None) -> float:
    """Lag-1 autocorrelation sum(r_i r_i+1) / sum(r_i^2) of residuals in row order (NaN: fewer than 3)."""
    if r is None:
        return math.nan
    r = np.asarray(r, dtype=float)
    r = r[np.isfinite(r)]
    if len(r) < 3 or not np.any(r):
        return math.nan
    return float(np.dot(r[:-1], r[1:]) / np.dot(r, r))


@dataclass(frozen=True)
class JointSetup:
    """What a joint calibration fits, and how.

    Attributes
    ----------
    base : CellParams
        The yarn's start values (B, d, in-plane width, m), its friction law, rules and effect
        parameters held fixed; the knit geometry is each specimen's.
    shared : tuple of str
        Yarn variables fitted, shared by every specimen: :data:`YARN_VARIABLES` and the
        variables of ``effects`` (e.g. ``compaction_k``).
    per_specimen : tuple of str
        Variables fitted per specimen: :data:`SPECIMEN_VARIABLES` (a geometry needs an uncertainty
        > 0 on every specimen).
    effects : tuple of str
        Effects switched on (:data:`knitsim.cell.effects.EFFECT_NAMES`).
    bounds : dict
        ``name -> (low, high)``: B [N mm^2], d and in_plane_width [mm], m, effect variables;
        phi0 as a fraction of phimax.  Defaults: B x/ 30, d x/ 2 (below W0/4), w in [d, W0/4),
        m in [0, 1], the effects' own (EFFECT_SPECS), phi0 in [-1, 1]; L, W0, C0 within 4 sd.
    fixed : dict
        Effect parameters held fixed (EffectSet field names).
    max_increment : float
        Largest strain increment of the program.
    starts, refine : int
        Latin-hypercube starts screened (besides the setup's own), and best ones refined.
    seed : int
        Seed of the Latin hypercube.
    max_nfev : int
        Least-squares evaluations per refined start.
    device : str
        Warp device.
    phi0_starts : tuple of float or None
        Per specimen, the start of its phi0 [rad] (None or absent: the base's).
    objective : str
        What a banded specimen's rows are fitted to: ``"midline"``, the band's mid-line with the sd of
        each row (:mod:`knitsim.calibration.specimen`: half-width, at least the force accuracy); ``"band"``,
        the band likelihood with a heavy tail (:meth:`knitsim.calibration.specimen.SpecimenData.band_residuals`:
        the model anywhere inside the band at no cost, just outside it a Gaussian of the force accuracy,
        far outside a Cauchy tail), refined from each mid-line solution (:func:`calibrate_joint`).  A
        specimen without a band is fitted to its curve (with the same tail under ``"band"``).
    zero : str
        What the files' 0 N is (module docstring, "The files' zero", :data:`ZERO_MODES`): ``"absolute"``
        (the model's 0 N; the default, here and in the scene), ``"tared"`` (the model's force at grip strain
        0: a load cell zeroed with the knit mounted) or ``"fitted"`` (a force offset per specimen, fitted).
    """

    base: CellParams
    shared: tuple
    per_specimen: tuple = ("phi0",)
    effects: tuple = ()
    bounds: dict = field(default_factory=dict)
    fixed: dict = field(default_factory=dict)
    max_increment: float = 0.005
    starts: int = 48
    refine: int = 3
    seed: int = 0
    max_nfev: int = 100
    device: str = "cpu"
    phi0_starts: tuple = ()
    objective: str = "midline"
    zero: str = "absolute"


#: objectives of a banded specimen's rows (JointSetup.objective)
OBJECTIVES = ("midline", "band")
#: what a file's 0 N is (JointSetup.zero; module docstring, "The files' zero")
ZERO_MODES = ("absolute", "tared", "fitted")


def check_zero(value, key: str = "calibration.zero") -> str:
    """``value`` if it is one of :data:`ZERO_MODES`, else a KnitsimInputError naming ``key`` and the three."""
    if not isinstance(value, str) or value not in ZERO_MODES:
        raise KnitsimInputError(f"{key} = {value!r}: expected one of {', '.join(repr(m) for m in ZERO_MODES)} "
                                "(absolute: the files' 0 N is the model's; tared: the files' 0 N is the model's force "
                                "at grip strain 0, a load cell zeroed with the knit mounted; fitted: a force offset "
                                "per specimen)")
    return value


@dataclass(frozen=True)
class Estimate:
    """One calibrated parameter.

    Attributes
    ----------
    name : str
        ``B``, ``d``, ``in_plane_width``, ``m``, an effect variable, or ``phi0`` / ``L`` / ``W0`` / ``C0``.
    specimen : str or None
        The specimen of a per-specimen parameter (None: shared by all).
    value, std_error : float
        In ``unit``.
    unit : str
    low, high : float
        The range it was fitted in (same unit; phi0's at the fitted m).
    at_bound : str or None
        ``"low"`` / ``"high"`` when within 0.1 % of the range of a bound, else ``"not identified"`` when
        it is not identified (``not_identified``); ``bound_note`` says what it means.
    bound_note : str
    stated : float or None
        A geometry's stated value (L, W0, C0) [mm]; ``deviation_sd`` its distance from it in prior sds.
    deviation_sd : float or None
    not_identified : str
        Empty when the rows set it; else the rule that says they do not (:data:`NOT_IDENTIFIED_SHARE`):
        its standard error is not finite (the rows do not depend on it), or larger than half its range
        (any value in the range fits as well).  Set whether or not it is at a bound.
    """

    name: str
    specimen: str | None
    value: float
    std_error: float
    unit: str
    low: float
    high: float
    at_bound: str | None = None
    bound_note: str = ""
    stated: float | None = None
    deviation_sd: float | None = None
    not_identified: str = ""

    @property
    def label(self) -> str:
        return self.name if self.specimen is None else f"{self.name}[{self.specimen}]"

    def as_dict(self) -> dict:
        return {"name": self.name, "specimen": self.specimen, "value": self.value, "std_error": self.std_error,
                "unit": self.unit, "low": self.low, "high": self.high, "at_bound": self.at_bound,
                "bound_note": self.bound_note, "stated": self.stated, "deviation_sd": self.deviation_sd,
                "not_identified": self.not_identified}


@dataclass(frozen=True)
class SpecimenFit:
    """How the calibrated model fits one specimen.

    Attributes
    ----------
    name : str
    params : CellParams
        The specimen's cell (the shared yarn with its own knit).
    wales : float
        Wales across the specimen (width / W0); 1 when the forces are per wale.
    strain, target_N, simulated_N, sigma_N : ndarray, shape [n]
        Rows, measured (target) and simulated force, sd.
    band_low_N, band_high_N : ndarray or None
    in_band_fraction : float or None
        Share of the rows (of the strain range) where the simulation lies inside the band.
    rms_N, rms_rel : float
        RMS of simulated - target [N], and relative to the target's RMS.
    chi2 : float
        Sum of squared weighted residuals of its rows (of the setup's objective).
    status : str
        Worst cell status over the rows (``ok`` when every row solved).
    pretension : float
        The knit's strain at grip strain 0 (0: at rest); the rows are knit strains
        ``(1 + pretension)(1 + grip strain) - 1``.
    pretension_N : float
        The model's force at grip strain 0 [N] (total, or per wale): its rest state's, or with a pretension
        the force the pretension implies.
    in_band_tolerant : float or None
        Share of the rows inside the band widened by the force reading's accuracy
        (:meth:`SpecimenData.in_band_tolerant`).
    residuals : ndarray or None
        The weighted residual of each row under the fit's objective (``objective``); ``chi2`` is the
        sum of their squares.
    objective : str
        ``"midline"`` or ``"band"`` (:class:`JointSetup`).
    offset_N : float or None
        The fitted force offset (None: ``zero`` not ``"fitted"``): the model's force plus it is what the rows are fitted
        to (``rms_N``, the band shares, ``chi2``, ``residuals``); ``simulated_N`` is the model's own force
        (what the written scenes run).  In ``offset_unit``: the file's zero is the model's at ``-offset_N``.
    offset_se_N : float
        Its standard error (the noise of the weighted mean and the other variables' covariance).
    offset_unit : str
        ``"N (total)"`` or ``"N per wale"``: the specimen's force column.
    zero : str
        The setup's :attr:`JointSetup.zero`.
    tare_N : float or None
        With ``zero = "tared"``, the model's force at grip strain 0 [N, in ``offset_unit``] subtracted from
        its force at every row (None otherwise): the model's force less it is what the rows are fitted to;
        ``simulated_N`` is the model's own force.
    rest_N, rest_sd_N : float
        The specimen's files' force at rest and its sd (:attr:`SpecimenData.rest_N`; NaN: not known), for
        the zero check of ``zero = "absolute"`` (:attr:`zero_check`).
    pretension_se_N : float
        The standard error of ``pretension_N`` from the fit's covariance (:func:`_zero_std_errors`; inf: the
        rows do not set it; NaN: not known).
    zero_cost, zero_witness_N, zero_witness_dchi2 : float
        The zero check's statistic (:func:`_zero_costs`; NaN: not computed, read as (gap / rest_sd_N)^2): the
        cost of the file's reading at rest as one more row, the least (a refit with it) of the rows' chi2 rise
        in s^2 plus ((model at grip strain 0 - rest_N) / rest_sd_N)^2; to first order (gap / sqrt(rest_sd^2 +
        pretension_se^2))^2.  The model's force at grip strain 0 at that point, and its chi2 rise in s^2.
    """

    name: str
    params: CellParams
    wales: float
    strain: np.ndarray
    target_N: np.ndarray
    simulated_N: np.ndarray
    sigma_N: np.ndarray
    band_low_N: np.ndarray | None
    band_high_N: np.ndarray | None
    in_band_fraction: float | None
    rms_N: float
    rms_rel: float
    chi2: float
    status: str
    pretension: float = 0.0
    pretension_N: float = 0.0
    in_band_tolerant: float | None = None
    residuals: np.ndarray | None = None
    objective: str = "midline"
    offset_N: float | None = None
    offset_se_N: float = math.nan
    offset_unit: str = ""
    zero: str = "absolute"
    tare_N: float | None = None
    rest_N: float = math.nan
    rest_sd_N: float = math.nan
    pretension_se_N: float = math.nan
    zero_cost: float = math.nan
    zero_witness_N: float = math.nan
    zero_witness_dchi2: float = math.nan

    @property
    def shift_N(self) -> float:
        """What is added to the model's force for the rows: the fitted offset, minus the tare, or 0."""
        if self.offset_N is not None:
            return float(self.offset_N)
        if self.tare_N is not None:
            return -float(self.tare_N)
        return 0.0

    def _zero_gap(self) -> tuple[float, float, float] | None:
        """With ``zero = "absolute"``: (the gap the zero check reads, the model's force at grip strain 0 less the
        file's at rest; the file's sd there; the check's statistic in sd, sqrt(``zero_cost``), or gap / sd where
        that was not computed), or None where either force is not known."""
        if self.zero != "absolute" or not (math.isfinite(self.rest_N) and math.isfinite(self.pretension_N)):
            return None
        sd = self.rest_sd_N if math.isfinite(self.rest_sd_N) else 0.0
        gap = self.pretension_N - self.rest_N
        if not math.isnan(self.zero_cost):
            return gap, sd, math.sqrt(max(self.zero_cost, 0.0))
        return gap, sd, (gap / sd if sd > 0 else math.inf)

    def _zero_screened(self) -> tuple[float, float, float] | None:
        """:meth:`_zero_gap` where the file reads at rest below the fitted model's force at grip strain 0 by more
        than ZERO_CHECK_SD of its noise sd and ZERO_CHECK_SHARE of its peak (what the check then reads against
        the fit's freedom), else None."""
        g = self._zero_gap()
        if g is None:
            return None
        gap, sd, _ = g
        # below only: above, the first readings of a clean file (rows the fit does not include: they start at one
        # row step) lay 20 sd above a fit within its noise in a probe's clean pair, which a flag would misread
        if not (gap > ZERO_CHECK_SD * sd and gap > ZERO_CHECK_SHARE * self.peak_N):
            return None
        return g

    @property
    def zero_check(self) -> str | None:
        """With ``zero = "absolute"``: the flag of a file that reads at rest more than ZERO_CHECK_SHARE of its peak
        below the fitted model's force at grip strain 0 (``pretension_N``), and beyond ZERO_CHECK_SD sd by the
        check's statistic (``zero_cost``: the file's reading at rest as one more row, against the fit's freedom
        there), or None: a load cell zeroed with the knit mounted.  Where the rows do not set the force at rest
        (few rows, or rows from past the knit's first slide) a fit about as good makes the file's reading, and
        :attr:`zero_note` says the zero cannot be told instead.  The fit is shared: one
        specimen's wrong zero pulls the yarn and can show in another's check (a re-probe's tared file left the
        other, right one flagged), so the flag names the disagreement, not which file is wrong."""
        g = self._zero_screened()
        if g is None or not g[2] > ZERO_CHECK_SD:
            return None
        gap, sd, n_sd = g
        unit = " per wale" if self.offset_unit == "N per wale" else ""
        # (gap > 0 here: only a reading below the model is flagged)
        by = (f"{n_sd:.3g} sd and " if math.isfinite(n_sd) else "") + f"{100 * gap / max(self.peak_N, 1e-300):.3g} % of its peak"
        if gap > self.peak_N:
            # the knit at rest carries more than the file's largest reading: no zero explains that, a scale does
            # (a blind probe's kN read as N, 493 % of the peak, was sent to zero = "tared")
            return (f"specimen {self.name} ({by} below the model at grip strain 0): the fitted knit carries "
                    f"{self.pretension_N:.4g} N{unit} at rest, more than the file's largest reading "
                    f"({self.peak_N:.4g} N{unit}): a force in another unit (kN or mN read as N), or the specimen's "
                    "wales or width not the tested one's? (the fit is shared: a wrong scale in any specimen's file "
                    "can show here)")
        return (f"specimen {self.name} ({by} below the model at grip strain 0): the file reads {self.rest_N:.4g} N"
                f"{unit} at rest where the fitted knit carries {self.pretension_N:.4g} N{unit}: a load cell zeroed "
                'with the knit mounted? set [calibration] zero = "tared" (or "fitted"); or its force scale (unit, '
                "wales, width) is not the model's (the fit is shared: a wrong zero or scale in any specimen's file can "
                "show here)")

    @property
    def zero_note(self) -> str | None:
        """With ``zero = "absolute"``: where the file reads at rest below the fitted model's force at grip strain 0
        by more than ZERO_CHECK_SD noise sd and ZERO_CHECK_SHARE of its peak, but within ZERO_CHECK_SD sd by the
        check's statistic (``zero_cost``: a fit of its rows about as good makes the file's reading): the zero
        cannot be told, said (a note, not a flag), else None.  A zero taken with the knit mounted would read so
        too, and is not seen."""
        g = self._zero_screened()
        if g is None or g[2] > ZERO_CHECK_SD:
            return None
        unit = " per wale" if self.offset_unit == "N per wale" else ""
        return (f"specimen {self.name}: its zero cannot be checked: the file reads {self.rest_N:.4g} N{unit} at rest, "
                f"the fitted knit carries {self.pretension_N:.4g} +- {self.pretension_se_N:.3g} N{unit} at grip strain "
                f"0, and a fit of the rows worse by chi2 {self.zero_witness_dchi2:.3g} s^2 carries "
                f"{self.zero_witness_N:.4g} N{unit} there ({g[2]:.3g} sd from the file's reading, counting both; "
                f"flagged beyond {ZERO_CHECK_SD:g}): its rows (grip strain {float(self.strain[0]):g} to "
                f"{float(self.strain[-1]):g}) do not set the force at rest. A load cell zeroed with the knit mounted "
                'would not be seen: if it was, set [calibration] zero = "tared"')

    @property
    def force_unit(self) -> str:
        """The unit of its forces as read (``target_N``, ``rms_N``, ``pretension_N``): ``"N"`` (total) or ``"N per
        wale"`` (a force-per-wale column: a probe's per-wale file was reported with an RMS of 0.00032 "N")."""
        return "N per wale" if self.offset_unit == "N per wale" else "N"

    @property
    def dof_rows(self) -> int:
        """Its rows less its fitted offset (the degrees of freedom of its chi2 per row)."""
        return len(self.strain) - (0 if self.offset_N is None else 1)

    @property
    def chi2_per_row(self) -> float:
        """chi2 / (rows - 1 for a fitted offset)."""
        return self.chi2 / max(self.dof_rows, 1)

    @property
    def peak_N(self) -> float:
        """The largest measured force (target) of its rows."""
        return float(np.max(np.abs(self.target_N))) if len(self.target_N) else 0.0

    @property
    def offset_share(self) -> float:
        """|offset| / peak measured force (NaN without an offset)."""
        if self.offset_N is None or not self.peak_N > 0:
            return math.nan
        return abs(self.offset_N) / self.peak_N

    def as_dict(self, curves: bool = True) -> dict:
        out = {"name": self.name, "wales": self.wales, "in_band_fraction": self.in_band_fraction,
               "offset_N": self.offset_N, "offset_se_N": self.offset_se_N if self.offset_N is not None else None,
               "offset_unit": self.offset_unit if self.offset_N is not None or self.tare_N is not None else None,
               "zero": self.zero, "tare_N": self.tare_N,
               "rest_N": self.rest_N if math.isfinite(self.rest_N) else None,
               "rest_sd_N": self.rest_sd_N if math.isfinite(self.rest_sd_N) else None,
               "pretension_se_N": None if math.isnan(self.pretension_se_N) else self.pretension_se_N,
               "zero_cost": None if math.isnan(self.zero_cost) else self.zero_cost,
               "pretension": self.pretension, "pretension_N": self.pretension_N,
               "in_band_tolerant": self.in_band_tolerant, "objective": self.objective,
               "rms_N": self.rms_N, "rms_rel": self.rms_rel, "chi2": self.chi2, "rows": int(len(self.strain)),
               "status": self.status, "params": self.params.as_dict()}
        if curves:
            out["curve"] = {"strain": self.strain.tolist(), "target_N": self.target_N.tolist(),
                            "simulated_N": self.simulated_N.tolist(), "sigma_N": self.sigma_N.tolist()}
            if self.offset_N is not None:       # what the rows were fitted to: the model plus its offset
                out["curve"]["simulated_plus_offset_N"] = (self.simulated_N + self.offset_N).tolist()
            if self.tare_N is not None:         # what the rows were fitted to: the model less its tare
                out["curve"]["simulated_less_tare_N"] = (self.simulated_N - self.tare_N).tolist()
            if self.band_low_N is not None:
                out["curve"].update(band_low_N=self.band_low_N.tolist(), band_high_N=self.band_high_N.tolist())
        return out


@dataclass(frozen=True)
class OneYarnCheck:
    """Whether the specimens look like one yarn (:func:`one_yarn_check`).

    The joint fit (one yarn, each specimen its own knit) against the same fit with every shared variable
    made each specimen's own (a yarn per specimen, its knit and priors as before), refined from the
    joint solution: a likelihood-ratio test of nested models, read as an F test (Chow's test of one
    regression against one per group) so that it holds whatever the scale of the rows' sds (the
    covariance's ``s^2`` is estimated the same way).

    Attributes
    ----------
    ran : bool
        False when it was not run (``why_not``): one specimen, nothing shared, the fit did not converge
        or a cell did not solve (its chi2 is then not its minimum), or too few rows.
    why_not : str
    specimens : tuple of str
    shared : tuple of str
        The variables made each specimen's own.
    chi2_joint : float
        chi2 of the joint fit (rows and priors).
    chi2_joint_each, chi2_own_each : tuple of float
        Per specimen: its rows and priors under the joint fit, and with its own yarn.
    dof : int
        Variables added: ``len(shared) x (specimens - 1)``.
    dof_resid : int
        n - k - dof (rows and priors less the variables of the fit with a yarn per specimen).
    F, p : float
        ``F = [(chi2_joint - chi2_own) / dof] / [chi2_own / dof_resid]`` and its upper tail under
        F(dof, dof_resid): the chance of a drop at least this large if the specimens are one yarn.
    own_yarns : tuple of dict
        Per specimen, its own yarn's values (``shared`` names, reported units).
    units : dict
    converged : tuple of bool
        Whether each own-yarn refinement converged (one that did not makes the test conservative: its
        chi2 is above its minimum, the drop smaller).
    nfev : int
        Evaluations of the refinements (each one specimen's cells: 1 / specimens of a joint evaluation).
    wall_s : float
    largest_pull : tuple or None
        ``(label, deviation_sd, stated, unit)``: the per-specimen prior furthest from its stated value
        (in prior sds) in the joint fit, where any is fitted.
    threshold : float
        p below which it flags (:data:`ONE_YARN_P`).
    objective : str
        The calibration's objective.  The chi2s are always the mid-line's (Gaussian rows): under ``"band"``,
        whose box likelihood has no residual variance for the F test to read (0 anywhere inside the band), the
        check tests the mid-line fit the band likelihood started from (:func:`calibrate_joint`).
    """

    ran: bool
    why_not: str = ""
    specimens: tuple = ()
    shared: tuple = ()
    chi2_joint: float = math.nan
    chi2_joint_each: tuple = ()
    chi2_own_each: tuple = ()
    dof: int = 0
    dof_resid: int = 0
    F: float = math.nan
    p: float = math.nan
    own_yarns: tuple = ()
    units: dict = field(default_factory=dict)
    converged: tuple = ()
    nfev: int = 0
    wall_s: float = 0.0
    largest_pull: tuple | None = None
    threshold: float = ONE_YARN_P
    objective: str = "midline"

    @property
    def chi2_own(self) -> float:
        return float(sum(self.chi2_own_each))

    @property
    def flagged(self) -> bool:
        return self.ran and self.p < self.threshold

    def yarn_text(self) -> str:
        """Each own yarn's values: ``B 0.25 | 0.57 N mm^2; m ...`` (specimens in order)."""
        parts = []
        for n in self.shared:
            u = self.units.get(n, "")
            parts.append(f"{n} " + " | ".join(f"{y[n]:.4g}" for y in self.own_yarns) + (f" {u}" if u and u != "-" else ""))
        return "; ".join(parts) + f" ({' | '.join(self.specimens)})"

    def pull_text(self) -> str:
        if self.largest_pull is None:
            return ""
        label, dev, stated, unit = self.largest_pull
        return f"{label}, {abs(dev):.2g} prior sd from its stated {stated:.4g} {unit}".rstrip()

    def flag(self) -> str:
        """The flag line (empty when not flagged)."""
        if not self.flagged:
            return ""
        pull = self.pull_text()
        # two specimens, or more (a probe's four read "makes both curves", "neither's")
        both, neither = (("both curves", "neither's") if len(self.specimens) == 2 else
                         (f"all {len(self.specimens)} curves", "none of theirs"))
        return (f"the specimens do not look like one yarn (p = {self.p:.2g} < {self.threshold:g}): with a yarn each "
                f"({', '.join(self.shared)}) they fit better than noise explains ("
                + ("the mid-line fit the band likelihood started from: " if self.objective == "band" else "")
                + f"chi2 {self.chi2_joint:.4g} -> "
                f"{self.chi2_own:.4g}, F = {self.F:.3g} on {self.dof} and {self.dof_resid} dof), each its own "
                f"{self.yarn_text()}; one yarn makes {both} only with worse rows or knits moved from their "
                "stated values" + (f" (the largest move: {pull})" if pull else "") + ": they are different yarns, "
                f"or the model cannot make {both} with one yarn; the yarn calibrated on them is {neither}")

    def as_dict(self) -> dict:
        return {"ran": self.ran, "why_not": self.why_not, "flagged": self.flagged, "specimens": list(self.specimens),
                "shared": list(self.shared), "chi2_joint": self.chi2_joint, "chi2_own": self.chi2_own if self.ran else None,
                "chi2_joint_each": list(self.chi2_joint_each), "chi2_own_each": list(self.chi2_own_each),
                "dof": self.dof, "dof_resid": self.dof_resid, "F": self.F, "p": self.p, "threshold": self.threshold,
                "objective": self.objective,
                "own_yarns": [dict(y) for y in self.own_yarns], "units": dict(self.units),
                "converged": list(self.converged), "nfev": self.nfev, "wall_s": self.wall_s,
                "largest_pull": None if self.largest_pull is None else
                {"label": self.largest_pull[0], "deviation_sd": self.largest_pull[1], "stated": self.largest_pull[2],
                 "unit": self.largest_pull[3]}}


def _unit_text(unit: str) -> str:
    """`` unit`` after a value, nothing for a dimensionless one (``-``, which read as a dash there)."""
    return "" if unit in ("", "-") else f" {unit}"


@dataclass(frozen=True)
class JointResult:
    """A joint calibration.

    Attributes
    ----------
    estimates : list of Estimate
        Shared parameters first, then each specimen's.
    correlation : ndarray, shape [k, k]
        Correlations of the estimates (same order).
    fits : list of SpecimenFit
    chi2 : float
        Weighted residual sum of squares, rows and priors.
    n, k : int
        Rows (and prior rows) and fitted variables.
    s2 : float
        chi2 / (n - k).
    variance_factor : float
        The covariance's factor, max(s2, 1) (NaN: not recorded).
    row_information : dict or None
        Each specimen's information per row in the covariance, (1 - rho) / (1 + rho) (:func:`_row_information`).
    success : bool
        The least squares converged and every specimen's cell solved on every row.
    message : str
    starts : list of dict
        Each refined start: its cost before and after, evaluations.
    nfev : int
        Least-squares evaluations of the chosen start.
    wall_s : float
    setup : JointSetup
    yarn : CellParams
        The calibrated yarn on the first specimen's knit (the shared values, effects and rules).
    converged : bool or None
        Whether the least squares of the chosen start converged (None: not recorded, read from ``success``).
    optimizer_message : str
        The least squares' own message for the chosen start.

    one_yarn : OneYarnCheck or None
        Whether the specimens look like one yarn (None: not recorded).

    ``k`` counts the force offsets (one per specimen, ``setup.zero = "fitted"``) with the variables; ``notes``
    (not flags) names each offset above :data:`OFFSET_NOTE_SHARE` of its specimen's peak measured force.

    ``flags`` (one line each): the optimiser's failure (with its message), every parameter at a bound,
    every parameter not identified (with the rule), every specimen whose cell did not solve on every row,
    with ``zero = "absolute"`` every specimen whose file reads at rest well below the fitted knit's force at
    grip strain 0 (:attr:`SpecimenFit.zero_check`), specimens that do not look like one yarn (``one_yarn``).
    A result with a flag is not a calibration to use as it is (``usable``).
    """

    estimates: list
    correlation: np.ndarray
    fits: list
    chi2: float
    n: int
    k: int
    s2: float
    success: bool
    message: str
    starts: list
    nfev: int
    wall_s: float
    setup: JointSetup
    yarn: CellParams
    converged: bool | None = None
    optimizer_message: str = ""
    one_yarn: OneYarnCheck | None = None
    variance_factor: float = math.nan
    row_information: dict | None = None

    def estimate(self, name: str, specimen: str | None = None) -> Estimate:
        for e in self.estimates:
            if e.name == name and e.specimen == specimen:
                return e
        raise KeyError((name, specimen))

    @property
    def flags(self) -> list[str]:
        """One line per reason not to use this calibration: the optimiser did not converge (its message),
        an estimate at a bound, an estimate not identified (which rule), a specimen whose cell did not solve,
        specimens that do not look like one yarn (:attr:`one_yarn`, what was measured and the largest knit move)."""
        # a force in another unit first: every other flag of such a fit follows from it
        out = [m for m in (_force_scale_flag(f) for f in self.fits) if m]
        converged = self.success if self.converged is None else self.converged
        if not converged:
            out.append("the fit failed: the optimiser (least squares) did not converge: "
                       + (self.optimizer_message or self.message).rstrip("."))
        for e in self.estimates:
            if e.at_bound in ("low", "high"):
                out.append(f"{e.label} = {e.value:.4g}{_unit_text(e.unit)} is at its {e.at_bound} bound ({e.bound_note})")
        for e in self.estimates:
            if e.specimen is None and _unidentified(e):
                out.append(f"{e.label} = {e.value:.4g} +- {e.std_error:.4g}{_unit_text(e.unit)} is not identified: "
                           + _unidentified(e))
        for f in self.fits:
            if f.status != "ok":
                out.append(f"specimen {f.name}: its cell did not solve on every row (worst status {f.status}): "
                           "the fitted curve is not the model's")
        out += [z for z in (f.zero_check for f in self.fits) if z]
        alone = self.unfit_alone
        for name, c in alone.items():
            fine = ", ".join(f"{n} {v:.3g}" for n, v in self.own_chi2_per_row.items() if n not in alone)
            out.append(f"specimen {name} is not made within its noise even with a yarn of its own (the one-yarn "
                       f"check's fit: chi2 per row {c:.3g}; alone, {fine}): its file, width, wales or knit is not "
                       "what the model is given (a width or force unit off), or it holds what the model lacks; "
                       "the shared yarn is pulled by it, so the others' misfit and the one-yarn test read it too: "
                       "check it, or calibrate without it")
        # per specimen (a re-probe: a clean specimen's rows diluted another's misfit in the pooled s2): its own
        # chi2 per row beyond POOR_FIT_S2 with residuals in waves; or the pooled s2 beyond it with waves
        per_row = {f.name: f.chi2_per_row for f in self.fits}      # rows less the specimen's offset
        waves = {f.name: residual_autocorrelation(f.residuals) for f in self.fits}
        waves = {name: a for name, a in waves.items() if a > POOR_FIT_AUTOCORRELATION}
        poor = [name for name in waves if per_row[name] > POOR_FIT_S2]
        if self.n > self.k and waves and (poor or self.s2 > POOR_FIT_S2):
            each = ", ".join(f"{name} {v:.3g}" for name, v in per_row.items())
            runs = ", ".join(f"{name} {a:.2f}" for name, a in waves.items())
            at_bound = [e.label for e in self.estimates if e.at_bound in ("low", "high")]
            out.append(f"the model does not make the curves within their noise"
                       + (f" ({', '.join(poor)})" if poor else "")
                       + f": chi2 / (n - k) = {self.s2:.3g}, chi2 per row {each} (flagged above {POOR_FIT_S2:g}: "
                       f"residuals over twice the noise the rows are weighted by), and the residuals run in waves, "
                       f"not row to row (lag-1 autocorrelation {runs}; > {POOR_FIT_AUTOCORRELATION:g}): the curves "
                       "hold what the model lacks (`knitsim diagnose` names it)"
                       + (f", or what {', '.join(at_bound)} at its bound keeps it from fitting" if at_bound else "")
                       + "; the residual panel of each fit plot shows where")
        if self.one_yarn is not None and self.one_yarn.flagged:
            shared_at_bound = [e.label for e in self.estimates
                               if e.specimen is None and e.at_bound in ("low", "high")]
            line = self.one_yarn.flag()
            if shared_at_bound:
                # each specimen's own yarn then moves the parameter the bound holds: the test measures the bound
                line += (f" -- not a verdict while {', '.join(shared_at_bound)} sits at its bound: the specimens' "
                         "own yarns differ there because the bound holds the joint one; widen it and run again")
            out.append(line)
        return out

    @property
    def own_chi2_per_row(self) -> dict:
        """Each specimen's chi2 per row fitted alone with a yarn of its own (the one-yarn check's fits; its rows
        less its offset; empty where the check did not run)."""
        c = self.one_yarn
        if c is None or not c.ran or len(c.chi2_own_each) != len(self.fits):
            return {}
        return {f.name: float(v) / max(f.dof_rows, 1) for f, v in zip(self.fits, c.chi2_own_each)}

    @property
    def unfit_alone(self) -> dict:
        """The specimens not made within their noise even with a yarn of their own (``name -> chi2 per row``
        alone): beyond :data:`POOR_FIT_S2` alone, residuals in waves in the joint fit
        (:data:`POOR_FIT_AUTOCORRELATION`), while another specimen is made alone.  One such specimen pulls the
        shared yarn and the others with it (a probe's strip given width 6 for 60 mm beside two right ones:
        the misfit flag named all three, and the one-yarn test read its misfit)."""
        own = self.own_chi2_per_row
        waves = {f.name: residual_autocorrelation(f.residuals) > POOR_FIT_AUTOCORRELATION for f in self.fits}
        bad = {n: v for n, v in own.items() if v > POOR_FIT_S2 and waves.get(n)}
        return bad if len(bad) < len(own) else {}

    @property
    def zero(self) -> str:
        """The setup's :attr:`JointSetup.zero`."""
        return self.setup.zero

    @property
    def n_offsets(self) -> int:
        """Force offsets fitted: one per specimen with ``zero = "fitted"``, else 0 (counted in ``k``)."""
        return len(self.fits) if self.zero == "fitted" else 0

    @property
    def tares_N(self) -> dict:
        """With ``zero = "tared"``, each specimen's model force at grip strain 0 subtracted from its rows:
        ``name -> {value, unit}`` (empty otherwise)."""
        return {f.name: {"value": f.tare_N, "unit": f.offset_unit} for f in self.fits if f.tare_N is not None}

    @property
    def offsets_N(self) -> dict:
        """Each specimen's fitted force offset: ``name -> {value, std_error, unit, share_of_peak}`` (empty: off)."""
        return {f.name: {"value": f.offset_N, "std_error": f.offset_se_N, "unit": f.offset_unit,
                         "share_of_peak": f.offset_share} for f in self.fits if f.offset_N is not None}

    @property
    def notes(self) -> list[str]:
        """Notes, not flags: :attr:`offset_notes`, :attr:`zero_notes` and :attr:`knit_notes`."""
        return self.offset_notes + self.zero_notes + self.knit_notes

    @property
    def zero_notes(self) -> list[str]:
        """Each specimen whose zero the check of ``zero = "absolute"`` cannot tell (:attr:`SpecimenFit.zero_note`)."""
        return [z for z in (f.zero_note for f in self.fits) if z]

    @property
    def knit_notes(self) -> list[str]:
        """:meth:`knit_notes_of` every specimen."""
        return [x for f in self.fits for x in self.knit_notes_of(f.name)]

    def knit_notes_of(self, specimen: str) -> list[str]:
        """A specimen's own knit variable (phi0, L, W0, C0, pretension) that the rows do not set, with the
        variable it trades off against (its strongest correlation).  A note, not a flag: the yarn is what a
        calibration is used for, and its standard errors come from the covariance of every variable, so they
        include the freedom of the knit's (the yarn's own rules, a bound, a rival start, its standard error,
        flag it where that freedom reaches it); the specimen's scenes hold one of the values that fit as well.
        (A probe's three knits of one yarn: each knit's phi0 and W0 correlated -0.999, and every calibration,
        the yarn recovered within 1.6 standard errors, was NOT A CALIBRATION YOU CAN USE.)  A knit variable
        at a bound stays a flag: the bound holds the fit, and the yarn with it."""
        out = []
        labels = [e.label for e in self.estimates]
        for i, e in enumerate(self.estimates):
            why = _unidentified(e)
            if e.specimen != specimen or not why:
                continue
            row = np.abs(np.nan_to_num(np.asarray(self.correlation[i], dtype=float), nan=0.0))
            row[i] = 0.0
            j = int(np.argmax(row)) if row.size else 0
            partner = (f"; it trades off against {labels[j]} (correlation {self.correlation[i, j]:+.3f})"
                       if row.size and row[j] > 0.9 else "")
            out.append(f"specimen {e.specimen}: its knit's {e.name} = {e.value:.4g} +- {e.std_error:.4g}"
                       f"{_unit_text(e.unit)} is not identified ({why}){partner}: "
                       + ("the yarn's standard errors are not known either (flagged)" if math.isnan(e.std_error) else
                          "the yarn's standard errors include this freedom, so the yarn stands; the specimen's "
                          "scenes hold one of the values that fit as well"))
        return out

    @property
    def offset_notes(self) -> list[str]:
        """Each specimen whose fitted force offset exceeds OFFSET_NOTE_SHARE of its peak measured force and
        OFFSET_NOTE_SE standard errors (a re-probe: offsets within 1 SE of 0 got the note), with the cause its
        sign suggests."""
        out = []
        for f in self.fits:
            share = f.offset_share
            se = f.offset_se_N if math.isfinite(f.offset_se_N) and f.offset_se_N > 0 else 0.0
            if math.isfinite(share) and share > OFFSET_NOTE_SHARE and abs(f.offset_N) > OFFSET_NOTE_SE * se:
                # offset = file - model: below the model is a zero taken with the knit mounted
                cause = ("the file reads below the model: a load cell zeroed with the knit mounted reads its rest "
                         "force as zero" if f.offset_N < 0 else
                         "the file reads above the model: a load cell zero above zero, or a pretension")
                out.append(f"specimen {f.name}: its fitted force offset {f.offset_N:+.4g} +- {f.offset_se_N:.2g} "
                           f"{f.offset_unit} is {100 * share:.3g} % of its peak measured force ({f.peak_N:.4g} "
                           f"{f.offset_unit}): {cause}; check the zero")
        return out

    @property
    def usable(self) -> bool:
        """No flag: converged, every cell solved, no parameter at a bound, no yarn parameter not identified
        (a specimen's own knit variable not identified is a note: :attr:`knit_notes`), one yarn."""
        return self.success and not self.flags

    def as_dict(self, curves: bool = True) -> dict:
        return {"estimates": [e.as_dict() for e in self.estimates],
                "correlation": {"names": [e.label for e in self.estimates], "matrix": self.correlation.tolist()},
                "specimens": [f.as_dict(curves) for f in self.fits], "chi2": self.chi2, "n": self.n, "k": self.k,
                "s2": self.s2, "variance_factor": self.variance_factor,
                "row_information": None if self.row_information is None else dict(self.row_information),
                "success": self.success, "message": self.message, "flags": self.flags,
                "zero": self.zero, "n_offsets": self.n_offsets,
                "offsets_N": self.offsets_N, "tares_N": self.tares_N, "notes": self.notes,
                "usable": self.usable, "converged": self.success if self.converged is None else self.converged,
                "optimizer_message": self.optimizer_message,
                "one_yarn": None if self.one_yarn is None else self.one_yarn.as_dict(),
                "starts": self.starts, "nfev": self.nfev, "wall_s": self.wall_s,
                "effects": list(self.setup.effects), "shared": list(self.setup.shared),
                "per_specimen": list(self.setup.per_specimen)}


# ============================================================== the problem
@dataclass(frozen=True)
class _Var:
    name: str
    specimen: int | None        # None: shared
    lo: float
    hi: float


class _Problem:
    """Variables, transforms and batched evaluation of a joint calibration."""

    def __init__(self, specimens: Sequence[SpecimenData], setup: JointSetup):
        self.sp = list(specimens)
        self.setup = setup
        self.effects = check_effects(setup.effects, where="effects")
        base = setup.base.validated(where="yarn")
        self.base = base
        known_shared = set(YARN_VARIABLES)
        drop = {r for e in self.effects for r in EFFECT_SPECS[e].replaces}
        effect_vars = {v.name: v for e in self.effects for v in EFFECT_SPECS[e].variables}
        known_shared |= set(effect_vars)
        shared = tuple(setup.shared)
        for n in shared:
            if n not in known_shared:
                raise KnitsimInputError(f"calibration.shared: {n!r} is not a yarn variable (expected one of "
                                        f"{', '.join(sorted(known_shared))})")
            if n in drop:
                raise KnitsimInputError(f"calibration.shared: {n!r} is replaced by an effect "
                                        f"({', '.join(e for e in self.effects if n in EFFECT_SPECS[e].replaces)})")
        for n in setup.per_specimen:
            if n not in SPECIMEN_VARIABLES:
                raise KnitsimInputError(f"calibration.per_specimen: {n!r} is not a specimen variable (expected one of "
                                        f"{', '.join(SPECIMEN_VARIABLES)})")
            if n in GEOMETRY:
                for i, s in enumerate(self.sp):
                    if not s.uncertainty.get(n, 0.0) > 0:
                        raise KnitsimInputError(f"specimens[{i}].uncertainty.{n}: needed > 0 to fit {n} per "
                                                "specimen (its relative measurement uncertainty)")
            if n == "pretension":
                for i, s in enumerate(self.sp):
                    if not s.pretension_sd > 0:
                        raise KnitsimInputError(f"specimens[{i}].pretension_sd: needed > 0 to fit the pretension "
                                                "per specimen (the sd of its prior: how far the tester's pretension "
                                                "may have stretched the knit before the strain origin)")
        for i, s in enumerate(self.sp):
            for n in GEOMETRY:
                u = s.uncertainty.get(n, 0.0)
                if u > 0 and n not in setup.per_specimen:
                    # a stated uncertainty of a geometry not fitted would be ignored, the fit holding the value as
                    # stated, exactly (a probe's L stated 1 % off with sd 0.02, L not in per_specimen: one yarn
                    # read as two, p = 1e-12, m 5 standard errors off, nothing said of L)
                    raise KnitsimInputError(
                        f"specimens[{i}].uncertainty.{n} = {u!r}: {n} is not fitted (not in "
                        f"calibration.per_specimen), so the fit would hold it at its stated {s.knit[n]:g} mm exactly "
                        f"and ignore this uncertainty: add {n} to calibration.per_specimen, or set "
                        f"uncertainty.{n} = 0 (known)")
        if len(set(shared)) != len(shared) or len(set(setup.per_specimen)) != len(setup.per_specimen):
            raise KnitsimInputError("calibration: a variable is listed twice")
        if not self.sp:
            raise KnitsimInputError("specimens: none given")
        if setup.objective not in OBJECTIVES:
            raise KnitsimInputError(f"calibration.objective = {setup.objective!r}: expected one of "
                                    f"{', '.join(OBJECTIVES)}")
        names = [s.name for s in self.sp]
        if len(set(names)) != len(names):
            raise KnitsimInputError(f"specimens: two specimens named alike ({names})")
        refuse_repeated_tests(self.sp)
        steps = {round(float(s.strain[1] - s.strain[0]), 12) for s in self.sp}
        if len(steps) != 1 or any(not np.allclose(s.strain, s.strain[0] * np.arange(1, len(s.strain) + 1),
                                                  rtol=1e-9, atol=1e-12) for s in self.sp):
            raise KnitsimInputError("specimens: the rows must be one uniform strain grid (one row_step)")
        self.effect_vars = effect_vars
        self.shared = shared
        self.own = tuple(setup.per_specimen)
        user = dict(setup.bounds)
        for n in user:
            if n not in known_shared and n not in SPECIMEN_VARIABLES:
                raise KnitsimInputError(f"calibration.bounds: {n!r} is not a fitted variable")
            if n not in shared and n not in setup.per_specimen:
                # a bound on a variable held at its start value binds nothing (a blind probe's d = [0.01, 50]
                # without d in shared ran to the end without a word, d held at its start)
                where = "calibration.per_specimen" if n in SPECIMEN_VARIABLES else "calibration.shared"
                raise KnitsimInputError(f"calibration.bounds.{n} = {list(user[n])}: {n} is not fitted (not in "
                                        f"{where}), so its bounds would bind nothing: add {n} to {where}, or "
                                        "remove its bounds")
        self.user_bounds = user
        self.vars: list[_Var] = []
        for n in shared:
            self.vars.append(_Var(n, None, *self._fit_bounds(n)))
        for k, s in enumerate(self.sp):
            for n in self.own:
                self.vars.append(_Var(n, k, *self._fit_bounds(n, s)))
        self.k = len(self.vars)
        if self.k == 0:
            raise KnitsimInputError("calibration: nothing to fit (shared and per_specimen are empty)")
        self._check_knits()
        self._check_starts()
        for i, s in enumerate(self.sp):
            self._check_reach(s, f"specimens[{i}]")
        self.n_rows = sum(len(s.strain) for s in self.sp)
        self.n_prior = sum(1 for v in self.vars if v.name in GEOMETRY or v.name == "pretension")
        self.zero = check_zero(setup.zero, "JointSetup.zero")
        self.offsets = self.zero == "fitted"       # a fitted force offset per specimen
        self.tared = self.zero == "tared"          # rows less the model's force at grip strain 0
        # the fitted parameters: the variables and a force offset per specimen (projected out, not in x)
        self.k_total = self.k + (len(self.sp) if self.offsets else 0)
        if self.n_rows <= self.k_total:
            raise KnitsimInputError(f"specimens: {self.n_rows} rows cannot fit {self.k} variables"
                                    + (f" and {len(self.sp)} force offsets" if self.offsets else ""))
        # one program through every row: the longest specimen's (the others' rows are its first ones)
        longest = max(self.sp, key=lambda s: len(s.strain))
        curve = MeasuredCurve(longest.strain, longest.target_N, np.ones(len(longest.strain), int),
                              np.ones(len(longest.strain), int), source=longest.name)
        self.program, rows = program_for_curve(curve, setup.max_increment)
        self.rows = [rows[:len(s.strain)] for s in self.sp]
        self.pretension = "pretension" in self.own or any(s.pretension > 0 for s in self.sp)
        if self.tared and self.pretension:
            # the tare would be the model's force at the pretensioned start, read off the fit's first increment
            # by interpolation from the rest state: too coarse where the knit stiffens inside it (a probe: 0.607
            # against 0.792 N of the pretensioned run itself), so refused rather than fitted wrong
            raise KnitsimInputError('calibration.zero = "tared" with a pretension is not supported (the tare at the '
                                    'pretensioned start is not resolved by the fit\'s program): use "fitted", or '
                                    '"absolute" with the files\' zero as read')
        if self.pretension:
            # a pretensioned knit runs from its rest state; its rows are knit strains
            # (1 + e_p)(1 + e_grip) - 1 between the increments (pretension_strain): one program from rest
            # to the last row at the largest pretension, the forces interpolated
            top_pre = max([s.pretension for s in self.sp]
                          + ([self._fit_bounds("pretension")[1]] if "pretension" in self.own else []))
            top = pretension_strain(float(longest.strain[-1]), float(top_pre))
            self.program = monotonic(top, setup.max_increment)
        self.calls = 0
        # the zero check's refit (_zero_costs): (specimen, the reading at rest it is to make, its sd), one row more
        self.rest_row: tuple | None = None
        # the rows' objective now (a band fit's first stage is the mid-line fit: calibrate_joint)
        self.objective = "midline"

    # ------------------------------------------------------------ bounds
    def _check_reach(self, s: SpecimenData, where: str) -> None:
        """Refuse rows the specimen's knit cannot reach in the loosest case the fit allows: a quarter-stitch
        cell is a straight yarn at C = C0 (1 + knit strain) = L/2 (:func:`reachable_strain`), at L's upper
        bound and C0's lower bound where they are fitted, through the largest pretension (knit strain
        (1 + e_p)(1 + grip strain) - 1, :func:`pretension_strain`)."""
        L, C0 = s.knit["L"], s.knit["C0"]
        loose = []
        if "L" in self.own:
            L *= math.exp(self._fit_bounds("L", s)[1])
            loose.append("L at its upper bound")
        if "C0" in self.own:
            C0 *= math.exp(self._fit_bounds("C0", s)[0])
            loose.append("C0 at its lower bound")
        pre = s.pretension
        if "pretension" in self.own:
            pre = max(pre, self._fit_bounds("pretension")[1])
            loose.append("the pretension at its upper bound")
        knit = reachable_strain(L, C0)
        grip = (1.0 + knit) / (1.0 + pre) - 1.0
        why = (f"a quarter-stitch cell is a straight yarn at C = C0 (1 + strain) = L/2: knit strain < L / (2 C0) - 1 "
               f"= {knit:.4g} with L = {L:.4g} mm, C0 = {C0:.4g} mm"
               + (f" ({', '.join(loose)}: the loosest the fit allows)" if loose else "")
               + (f"; through a pretension of {pre:.4g}, knit strain = (1 + {pre:.4g})(1 + grip strain) - 1"
                  if pre > 0 else ""))
        check_reach(s, grip, why, where)

    def _fit_bounds(self, name: str, s: SpecimenData | None = None) -> tuple[float, float]:
        b = self.base
        if name == "B":
            lo, hi = self.user_bounds.get("B", (b.B / 30.0, b.B * 30.0))
            if not 0 < lo < hi:
                raise KnitsimInputError(f"calibration.bounds.B = [{lo}, {hi}]: expected 0 < low < high [N mm^2]")
            return math.log(lo), math.log(hi)
        if name == "d":
            lo, hi = self.user_bounds.get("d", (0.5 * b.d, 2.0 * b.d))
            if not 0 < lo < hi:
                raise KnitsimInputError(f"calibration.bounds.d = [{lo}, {hi}]: expected 0 < low < high [mm]")
            return 0.0, 1.0                     # a fraction of [low, min(high, W0/4))
        elif name == "in_plane_width":
            return 0.0, 1.0                     # a fraction of [max(d, low), min(high, W0/4))
        elif name == "m":
            lo, hi = self.user_bounds.get("m", BASELINE_VARIABLES["m"].bounds)
            if not 0.0 <= lo < hi <= M_MAX:
                raise KnitsimInputError(f"calibration.bounds.m = [{lo}, {hi}]: expected 0 <= low < high <= {M_MAX:g} "
                                        f"({M_TOO_LARGE})")
        elif name == "phi0":
            lo, hi = self.user_bounds.get("phi0", (-1.0, 1.0))
            if lo < -1 or hi > 1:
                raise KnitsimInputError(f"calibration.bounds.phi0 = [{lo}, {hi}]: a fraction of phimax in [-1, 1]")
        elif name == "pretension":
            lo, hi = self.user_bounds.get("pretension", PRETENSION_RANGE)
            if not 0.0 <= lo < hi <= 0.5:
                raise KnitsimInputError(f"calibration.bounds.pretension = [{lo}, {hi}]: strains of the knit at grip "
                                        "strain 0, 0 <= low < high <= 0.5")
        elif name in GEOMETRY:
            u = s.uncertainty[name]
            lo, hi = self.user_bounds.get(name, (math.exp(-4 * u), math.exp(4 * u)))
            if not 0 < lo < 1 < hi:
                raise KnitsimInputError(f"calibration.bounds.{name} = [{lo}, {hi}]: factors on the stated value "
                                        "around 1 (e.g. [0.85, 1.15])")
            return math.log(lo), math.log(hi)
        else:
            lo, hi = self.user_bounds.get(name, self.effect_vars[name].bounds)
        if not lo < hi:
            raise KnitsimInputError(f"calibration.bounds.{name} = [{lo}, {hi}]: expected low < high")
        return float(lo), float(hi)

    @property
    def lo(self) -> np.ndarray:
        return np.array([v.lo for v in self.vars])

    @property
    def hi(self) -> np.ndarray:
        return np.array([v.hi for v in self.vars])

    def prior_pull(self, name: str, specimen: int | None, value: float) -> tuple[float | None, float | None]:
        """(stated value, distance from it in prior sds) of a knit variable with a prior: L, W0, C0 (stated in the
        scene, ``value`` their fitted relative change) and the pretension (stated 0); (None, None) for any other
        variable, and a distance of None where the prior's sd is 0 or the distance is not finite."""
        if name not in GEOMETRY and name != "pretension":
            return None, None
        s = self.sp[specimen]
        stated, sd = (s.knit[name], s.uncertainty[name]) if name in GEOMETRY else (0.0, s.pretension_sd)
        dev = float(value) / sd if sd > 0 else math.nan
        return float(stated), (dev if math.isfinite(dev) else None)

    def _check_knits(self) -> None:
        """Refuse a specimen whose knit as stated is no cell with the start yarn (the cell's own check, e.g. W0
        below 4 d: a W0 in cm), naming the specimen: before, only the first specimen's knit was checked (the scene's
        start cell), and a later one's ran the whole fit to a RuntimeError traceback ("the calibrated point is
        not an admissible cell")."""
        for i, s in enumerate(self.sp):
            try:
                self.base.replace(**s.knit).validated(where="cell")
            except KnitsimInputError as exc:
                raise KnitsimInputError(f"specimens[{i}].knit: the start yarn on specimen {s.name}'s knit as stated: "
                                        f"{exc}") \
                    from None

    def _check_starts(self) -> None:
        """Refuse a start (the scene's value) outside its variable's bounds: the fit would start from the nearest
        bound without a word (a blind probe's B = 5 with bounds [0.05, 2])."""
        b, W0s = self.base, [s.knit["W0"] for s in self.sp]
        for v in self.vars:
            if v.name == "phi0":
                # a specimen's own start (specimens[i].phi0, else friction.phi0), a fraction of phimax at the
                # start's m: outside the range it was clipped to its end without a word (degrees typed as rad)
                given = self.setup.phi0_starts[v.specimen] if v.specimen < len(self.setup.phi0_starts) else None
                value = b.phi0 if given is None else given
                if not v.lo * b.phimax - 1e-12 <= value <= v.hi * b.phimax + 1e-12:
                    key = f"specimens[{v.specimen}].phi0" if given is not None else "friction.phi0"
                    deg = (f" (in degrees it would be {math.radians(value):.4g} rad)"
                           if abs(math.radians(value)) <= b.phimax else "")
                    raise KnitsimInputError(
                        f"{key} = {value:g} rad: specimen {self.sp[v.specimen].name}'s phi0 start lies outside its "
                        f"range [{v.lo * b.phimax + 0.0:.4g}, {v.hi * b.phimax + 0.0:.4g}] rad ("
                        + ("+-phimax = atan(m)" if (v.lo, v.hi) == (-1.0, 1.0) else "calibration.bounds.phi0 x phimax")
                        + f", m = {b.m:g} the start){deg}: the fit would start from the nearest end; give phi0 in "
                        "radians within it")
                continue
            if v.specimen is not None:
                continue
            if v.name == "B":
                value, (lo, hi) = b.B, (math.exp(v.lo), math.exp(v.hi))
            elif v.name == "d":
                value, (lo, hi) = b.d, self.d_range(W0s)
            elif v.name == "in_plane_width" and b.in_plane_width is not None:
                # (none given: it starts from d, its range's own low end by construction)
                value, (lo, hi) = b.d_jam, self.w_range(b.d, W0s)
            elif v.name == "m":
                value, lo, hi = b.m, v.lo, v.hi
            else:
                continue
            if not lo * (1 - 1e-12) <= value <= hi * (1 + 1e-12):
                why = {"d": " (below W0/4 of the narrowest knit)", "in_plane_width": " (from d to W0/4 of the "
                       "narrowest knit)"}.get(v.name, "")
                unit = "" if UNITS.get(v.name, "-") == "-" else " " + UNITS[v.name]
                raise KnitsimInputError(
                    f"calibration: {v.name}'s start, the scene's {value:.6g}{unit}, lies outside its "
                    f"bounds [{lo:.6g}, {hi:.6g}]{why}: the fit would start from the nearest bound; change the scene's "
                    f"{v.name} or calibration.bounds.{v.name}")

    def w_range(self, d: float, W0s: Sequence[float]) -> tuple[float, float]:
        """Range of the in-plane width: from d (and its low bound) to W0/4 of the narrowest knit."""
        lo, hi = self.user_bounds.get("in_plane_width", (0.0, math.inf))
        return max(d, lo), min(hi, 0.999 * min(W0s) / 4.0)

    def d_range(self, W0s: Sequence[float]) -> tuple[float, float]:
        """Range of d: its bounds, below W0/4 of the narrowest knit (loops jammed at rest otherwise)."""
        lo, hi = self.user_bounds.get("d", (0.5 * self.base.d, 2.0 * self.base.d))
        return lo, max(lo, min(hi, 0.999 * min(W0s) / 4.0))

    # ------------------------------------------------------------ transforms
    def start(self) -> np.ndarray:
        """The setup's own point in the fit variables."""
        b = self.base
        x = []
        for v in self.vars:
            if v.name == "B":
                x.append(math.log(b.B))
            elif v.name == "d":
                lo, hi = self.d_range([s.knit["W0"] for s in self.sp])
                x.append((b.d - lo) / (hi - lo) if hi > lo else 0.0)
            elif v.name == "in_plane_width":
                lo, hi = self.w_range(b.d, [s.knit["W0"] for s in self.sp])
                x.append((b.d_jam - lo) / (hi - lo) if hi > lo else 0.0)
            elif v.name == "m":
                x.append(b.m)
            elif v.name == "phi0":
                given = (self.setup.phi0_starts[v.specimen] if v.specimen < len(self.setup.phi0_starts)
                         else None)
                phi0 = b.phi0 if given is None else given
                x.append(max(-1.0, min(1.0, phi0 / b.phimax)) if b.phimax > 0 else 0.0)
            elif v.name in GEOMETRY:
                x.append(0.0)
            elif v.name == "pretension":
                x.append(self.sp[v.specimen].pretension)
            elif v.name == "log10_dahl_sigma" and b.dahl_sigma > 0:
                x.append(math.log10(b.dahl_sigma))        # the scene's Dahl stiffness as the start
            elif hasattr(b.effects, v.name):
                x.append(float(getattr(b.effects, v.name)))   # the scene's effect parameter as the start
            else:
                x.append(self.effect_vars[v.name].start(b))
        return np.clip(np.array(x, float), self.lo, self.hi)

    def model_values(self, x: np.ndarray) -> tuple[dict, list[dict]]:
        """Shared values and each specimen's values in model units (phi0 as a fraction, w in mm)."""
        shared = {v.name: float(xi) for v, xi in zip(self.vars, x) if v.specimen is None}
        own = [dict() for _ in self.sp]
        for v, xi in zip(self.vars, x):
            if v.specimen is not None:
                own[v.specimen][v.name] = float(xi)
        if "B" in shared:
            shared["B"] = math.exp(shared["B"])
        for k, s in enumerate(self.sp):
            for g in GEOMETRY:
                own[k][g] = s.knit[g] * math.exp(own[k][g]) if g in own[k] else s.knit[g]
        if "d" in shared:
            lo, hi = self.d_range([o["W0"] for o in own])
            shared["d"] = lo + shared["d"] * (hi - lo)
        if "in_plane_width" in shared:
            d = shared.get("d", self.base.d)
            lo, hi = self.w_range(d, [o["W0"] for o in own])
            shared["in_plane_width"] = lo + shared["in_plane_width"] * (hi - lo)
        return shared, own

    def cell(self, shared: dict, own: dict) -> CellParams:
        """The cell of one specimen (validated; raises KnitsimInputError for an inadmissible point)."""
        values = dict(shared)
        values.update({n: v for n, v in own.items() if n != "pretension"})   # the load's, not the cell's
        return build_params(self.base, self.effects, values, self.setup.fixed)

    def cells_at(self, x: np.ndarray) -> list:
        """Each specimen's cell at ``x`` (None where inadmissible)."""
        shared, own = self.model_values(x)
        out = []
        for o in own:
            try:
                out.append(self.cell(shared, o))
            except KnitsimInputError:
                out.append(None)
        return out

    # ------------------------------------------------------------ simulation
    def simulate(self, cells: list) -> list:
        """Per (specimen index, CellParams or None): force per wale at the specimen's rows and status codes,
        and the force per wale of its rest state (the batch's, before the first increment)."""
        valid = [(i, c) for i, (k, c) in enumerate(cells) if c is not None]
        out: list = [None] * len(cells)
        if valid:
            self.calls += 1
            hist = run_batch([c for _, c in valid], self.program, device=self.setup.device)
            F, st = hist.force_per_wale, hist.status
            rest = hist.rest["F"] if hist.rest is not None else np.full(len(valid), np.nan)
            for j, (i, _) in enumerate(valid):
                k = cells[i][0]
                if self.pretension:
                    out[i] = (F[:, j], st[:, j], float(rest[j]))       # the whole history: rows read in residuals()
                    continue
                r = self.rows[k]
                out[i] = (np.where(r >= 0, F[np.maximum(r, 0), j], 0.0),
                          np.where(r >= 0, st[np.maximum(r, 0), j], STATUS_OK), float(rest[j]))
        return out

    def at_rows(self, k: int, sim: tuple, own: dict) -> tuple[np.ndarray, np.ndarray]:
        """Force per wale and status at specimen ``k``'s rows from its simulation (``simulate``)."""
        if not self.pretension:
            return sim[0], sim[1]
        F, st = sim[0], sim[1]
        e = pretension_strain(self.sp[k].strain, own.get("pretension", self.sp[k].pretension))
        hist = np.concatenate(([0.0], self.program.strain))
        f = np.interp(e, hist, np.concatenate(([0.0], F)))
        # a row is as good as the worst increment up to the one that reaches it
        worst = np.maximum.accumulate(st)
        idx = np.minimum(np.searchsorted(self.program.strain, e - 1e-12), len(st) - 1)
        return f, worst[idx]

    def at_zero(self, k: int, sim: tuple, own: dict) -> float:
        """Force per wale of specimen ``k``'s model at grip strain 0, from its simulation (``simulate``): its
        rest state's (what ``zero = "tared"`` subtracts; refused with a pretension, whose start the fit's
        program does not resolve)."""
        return float(sim[2])

    def at_grip_zero(self, k: int, sim: tuple, own: dict) -> float:
        """Force per wale of specimen ``k``'s model at grip strain 0, from its simulation (``simulate``): its rest
        state's, or with a pretension the fit's program read at the pretension strain (linearly from the rest
        state below the first increment).  What the zero check compares the file's reading at rest with
        (:attr:`SpecimenFit.pretension_N`, its standard error from the covariance's points: :func:`_covariance`)."""
        e_p = float(own.get("pretension", self.sp[k].pretension)) if self.pretension else 0.0
        if e_p <= 0.0:
            return float(sim[2])
        return float(np.interp(e_p, np.concatenate(([0.0], self.program.strain)),
                               np.concatenate(([float(sim[2])], sim[0]))))

    def offset(self, s: SpecimenData, force: np.ndarray, bad: np.ndarray) -> float:
        """Specimen ``s``'s best force offset [its force column's units] for the model force ``force`` at its
        rows: ``knitsim diagnose``'s law (:func:`knitsim.diagnosis.calibrate.offset_of`), the weighted mean
        of ``target - force`` with weights 1 / sd^2, the rows after a failed increment (``bad``) left out;
        0 unless ``zero = "fitted"``."""
        if not self.offsets:
            return 0.0
        return offset_of(force - s.target_N, np.where(bad, 0.0, 1.0 / s.sigma_N))

    def row_residuals(self, s: SpecimenData, force: np.ndarray, off: float) -> np.ndarray:
        """The weighted rows of specimen ``s`` for the model force ``force`` plus the offset ``off`` (0 unless
        ``zero = "fitted"``: :meth:`offset`)."""
        fitted_to = force + off
        if self.objective == "band":
            return s.band_residuals(fitted_to)
        return (fitted_to - s.target_N) / s.sigma_N

    def residuals(self, x: np.ndarray, sims: list, offsets_out: list | None = None,
                  zeros_out: list | None = None, failed_out: list | None = None) -> np.ndarray:
        """Weighted rows of every specimen (less each one's best force offset, with offsets on), then the
        geometry priors.  ``offsets_out``: a list the specimens' offsets are appended to (0 where a cell
        is inadmissible); ``zeros_out``: one the specimens' model forces at grip strain 0 are appended to, in
        their force column's units (:meth:`at_grip_zero`; NaN where a cell is inadmissible); ``failed_out``: one
        that gets a boolean array over the residuals, True where a residual is the fail residual
        (:data:`FAIL_RESIDUAL`: an inadmissible cell, or a row at or after a failed increment), no model's."""
        shared, own = self.model_values(x)
        parts = []
        failed = []
        rest_row = FAIL_RESIDUAL * 1e3                 # the zero check's row where its cell is inadmissible
        rest_failed = True
        for k, s in enumerate(self.sp):
            w = s.wales(own[k]["W0"]) if s.total else 1.0
            fail = FAIL_RESIDUAL * np.maximum(1.0, np.abs(s.target_N) / s.sigma_N)
            if sims[k] is None:
                parts.append(fail)
                failed.append(np.ones(len(fail), bool))
                if offsets_out is not None:
                    offsets_out.append(0.0)
                if zeros_out is not None:
                    zeros_out.append(math.nan)
                continue
            if zeros_out is not None:
                zeros_out.append(w * self.at_grip_zero(k, sims[k], own[k]))
            if self.rest_row is not None and self.rest_row[0] == k:
                rest_row = (w * self.at_grip_zero(k, sims[k], own[k]) - self.rest_row[1]) / self.rest_row[2]
                rest_failed = False
            f, st = self.at_rows(k, sims[k], own[k])
            if self.tared:                # the file's 0 N is the model's force at grip strain 0
                f = f - self.at_zero(k, sims[k], own[k])
            bad = np.maximum.accumulate(st != STATUS_OK)
            # variable projection: the offset that minimises this specimen's rows given x, in closed form
            off = self.offset(s, w * f, bad)
            if offsets_out is not None:
                offsets_out.append(off)
            r = self.row_residuals(s, w * f, off)
            parts.append(np.where(bad, fail, r))
            failed.append(np.asarray(bad, bool))
        for v, xi in zip(self.vars, x):
            if v.name in GEOMETRY:
                parts.append(np.array([xi / self.sp[v.specimen].uncertainty[v.name]]))
                failed.append(np.zeros(1, bool))
            elif v.name == "pretension":
                s = self.sp[v.specimen]
                parts.append(np.array([xi / s.pretension_sd]))     # prior: the strain origin at face value
                failed.append(np.zeros(1, bool))
        if self.rest_row is not None:
            parts.append(np.array([rest_row]))
            failed.append(np.array([rest_failed]))
        if failed_out is not None:
            failed_out.append(np.concatenate(failed))
        return np.concatenate(parts)

    def evaluate_points(self, X: Sequence[np.ndarray], offsets_out: list | None = None,
                        zeros_out: list | None = None, failed_out: list | None = None) -> list[np.ndarray]:
        """Residual vectors of several points, all in one launch (``offsets_out``: a list that gets each
        point's list of specimen offsets; ``zeros_out``: each point's list of the specimens' model forces at
        grip strain 0; ``failed_out``: each point's mask of fail residuals, :meth:`residuals`)."""
        jobs = []
        for x in X:
            for k, c in enumerate(self.cells_at(np.asarray(x))):
                jobs.append((k, c))
        sims = self.simulate(jobs)
        S = len(self.sp)
        out = []
        for i, x in enumerate(X):
            offs, zs = [], []
            out.append(self.residuals(np.asarray(x), sims[i * S:(i + 1) * S], offs, zs, failed_out))
            if offsets_out is not None:
                offsets_out.append(offs)
            if zeros_out is not None:
                zeros_out.append(zs)
        return out

    def evaluate_with_jacobian(self, x: np.ndarray, rel_step: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
        """Residuals at ``x`` and their forward-difference Jacobian, one launch (each specimen's cell
        perturbed only in the shared variables and its own)."""
        x = np.asarray(x, float)
        h = rel_step * np.maximum(np.abs(x), 1.0)
        h = np.where(x + h > self.hi, -h, h)
        points = [x] + [x + h[j] * np.eye(self.k)[j] for j in range(self.k)]
        cells = [self.cells_at(p) for p in points]
        jobs, index = [], {}
        for k in range(len(self.sp)):
            for j, p in enumerate(points):
                v = None if j == 0 else self.vars[j - 1]
                if j > 0 and v.specimen is not None and v.specimen != k:
                    continue
                index[(k, j)] = len(jobs)
                jobs.append((k, cells[j][k]))
        sims = self.simulate(jobs)
        r0 = self.residuals(x, [sims[index[(k, 0)]] for k in range(len(self.sp))])
        J = np.empty((len(r0), self.k))
        for j in range(1, self.k + 1):
            sj = [sims[index[(k, j)]] if (k, j) in index else sims[index[(k, 0)]] for k in range(len(self.sp))]
            J[:, j - 1] = (self.residuals(points[j], sj) - r0) / h[j - 1]
        return r0, J


# ============================================================== the fit
def _lhs(problem: _Problem, n: int, seed: int) -> list[np.ndarray]:
    if n <= 0:
        return []
    u = qmc.LatinHypercube(d=problem.k, seed=seed).random(n)
    lo, hi = problem.lo, problem.hi
    X = lo + u * (hi - lo)
    for j, v in enumerate(problem.vars):
        if v.name in GEOMETRY:
            # the stated geometry within +-1 sd: a start, not a claim
            s = problem.sp[v.specimen].uncertainty[v.name]
            X[:, j] = np.clip(-s + 2 * s * u[:, j], lo[j], hi[j])
    return [x for x in X]


def _reported(problem: _Problem, x: np.ndarray) -> tuple[list, np.ndarray, list, list]:
    """Names (name, specimen index), values and ranges in the reported variables at ``x``."""
    shared, own = problem.model_values(x)
    cells = problem.cells_at(x)
    names, vals, los, his = [], [], [], []
    for v, xi in zip(problem.vars, x):
        if v.specimen is None:
            val = shared[v.name]
            if v.name == "B":
                lo, hi = math.exp(v.lo), math.exp(v.hi)
            elif v.name == "d":
                lo, hi = problem.d_range([o["W0"] for o in own])
            elif v.name == "in_plane_width":
                lo, hi = problem.w_range(shared.get("d", problem.base.d), [o["W0"] for o in own])
            else:
                lo, hi = v.lo, v.hi
        else:
            k = v.specimen
            if v.name == "phi0":
                pm = cells[k].phimax if cells[k] is not None else 0.0
                val, lo, hi = xi * pm, v.lo * pm, v.hi * pm
            elif v.name == "pretension":
                val, lo, hi = xi, v.lo, v.hi
            else:
                st = problem.sp[k].knit[v.name]
                val, lo, hi = own[k][v.name], st * math.exp(v.lo), st * math.exp(v.hi)
        names.append((v.name, v.specimen))
        vals.append(val)
        los.append(lo)
        his.append(hi)
    return names, np.array(vals), los, his


def _fit_variables(problem: _Problem, x: np.ndarray, names: list, yv: np.ndarray) -> np.ndarray:
    """The fit variables of the reported values ``yv`` (inverse of model_values / :func:`_reported`; ``x`` gives
    the variables that are not reported, and ``names`` the reported ones' (name, specimen index))."""
    out = np.array(x, float)
    shared_d = problem.base.d
    W0s = [problem.sp[i].knit["W0"] for i in range(len(problem.sp))]
    for j, (n, spi) in enumerate(names):
        if n == "d" and spi is None:
            shared_d = yv[j]
        if n == "W0" and spi is not None:
            W0s[spi] = yv[j]
    for j, (n, spi) in enumerate(names):
        if spi is None:
            if n == "B":
                out[j] = math.log(yv[j])
            elif n == "d":
                lo, hi = problem.d_range(W0s)
                out[j] = (yv[j] - lo) / (hi - lo) if hi > lo else 0.0
            elif n == "in_plane_width":
                lo, hi = problem.w_range(shared_d, W0s)
                out[j] = (yv[j] - lo) / (hi - lo) if hi > lo else 0.0
            else:
                out[j] = yv[j]
        elif n == "phi0":
            m = problem.model_values(out)[0].get("m", problem.base.m)
            pm = math.atan(m)
            out[j] = yv[j] / pm if pm > 0 else 0.0
        elif n == "pretension":
            out[j] = yv[j]
        else:
            out[j] = math.log(yv[j] / problem.sp[spi].knit[n])
    return out


def _profile_probes(problem: _Problem, x: np.ndarray, cov: np.ndarray, chi2: float,
                    s2: float) -> list[tuple[float, np.ndarray]]:
    """Points :data:`PROBE_SE` standard errors out from the best on either side of each variable, the others
    held, as rivals (:func:`rival_rule`): each one's chi2 above the best's (in s^2) and its reported values.

    Under the best point's curvature such a point costs at least ``PROBE_SE^2`` = 16 s^2 (the others held
    cost no less than the profile, which re-fits them).  One within :data:`RIVAL_DCHI2` is a point that fits
    as well beyond :data:`RIVAL_SE` standard errors, as a rival start's would be: a flat or many-valleyed
    direction that the curvature hides, which the refined starts miss when they all fall into one valley (a
    blind probe's loose knit with the default refine = 3, from 12 or 32 starts: in_plane_width = 0.8233 +-
    0.0051 mm and no flag, where w = 0.62 .. 0.818 fit within 0.25 s^2 with the others held, the truth 0.79
    too).  Held, not moved along the profile: the profile's direction, from the same curvature, moved B and
    W0 of that knit by 4 of their own standard errors, through zero or into cells that fail.  One batched
    evaluation of 2 x k points (the covariance's own is k + 1); a point beyond a bound is clipped to it."""
    names, y, los, his = _reported(problem, x)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    pts = []
    for j in range(len(y)):
        if not (np.isfinite(se[j]) and se[j] > 0):
            continue
        for sign in (-1.0, 1.0):
            yv = np.array(y, float)
            yv[j] = min(max(y[j] + sign * PROBE_SE * se[j], los[j]), his[j])
            if yv[j] == y[j]:
                continue
            try:
                xp = _fit_variables(problem, x, names, yv)
            except (ValueError, ZeroDivisionError):          # a log of a value at zero
                continue
            if np.all(np.isfinite(xp)):
                pts.append(np.clip(xp, problem.lo, problem.hi))
    if not pts or not (s2 > 0):
        return []
    res = problem.evaluate_points(pts)
    return [((float(r @ r) - chi2) / s2, _reported(problem, p)[1]) for r, p in zip(res, pts)]


def _row_information(problem: _Problem, r: np.ndarray) -> list[float]:
    """Each specimen's information per row, (1 - rho) / (1 + rho) with rho the lag-1 autocorrelation of its
    residuals ``r`` at the solution (clipped at 0; NaN: 0): the variance of a mean of n AR(1) errors is that of
    n (1 - rho) / (1 + rho) independent ones.  1 under the band objective, whose residuals (0 anywhere inside
    the band) are no errors to correlate.  A probe's two knits with AR(1) noise of 0.8 (stated sds right): the
    yarn beyond 2 standard errors of the truth in 6 of 10 seeds, within 1.4 of them with the weights."""
    out, i = [], 0
    for s in problem.sp:
        n = len(s.strain)
        rho = residual_autocorrelation(r[i:i + n]) if problem.objective == "midline" else math.nan
        rho = max(rho, 0.0) if math.isfinite(rho) else 0.0
        out.append((1.0 - rho) / (1.0 + rho))
        i += n
    return out


def _covariance(problem: _Problem, x: np.ndarray, s2: float, rel_step: float = 1e-6,
                offset_gradient: list | None = None, information: list | None = None,
                zero_gradient: list | None = None, unknown: list | None = None) -> np.ndarray:
    """Covariance of the reported variables: FD Jacobian at the solution, each specimen's rows weighted by its
    :func:`_row_information` (``information``: a list that gets them), times ``s2`` (the caller's factor,
    max(s^2, 1)).

    The steps are taken in the fit's own variables (B's log, d and the in-plane width as fractions of their
    ranges, phi0 as a fraction of the friction cone phimax = atan(m), a geometry's log factor), inward from a
    bound as the fit's own Jacobian steps (:meth:`_Problem.evaluate_with_jacobian`), and the Jacobian is carried
    to the reported variables by the chain rule, J_y = J_x dx/dy (dx/dy by central differences of
    :func:`_fit_variables`, arithmetic only): the covariance of the reported variables is then the delta
    method's, dy/dx cov_x (dy/dx)^T.  Stepped in the reported variables (phi0 in rad held), m stepped down
    from its bound shrank the cone below a phi0 at +-phimax: every cell inadmissible, the fail residuals
    (:data:`FAIL_RESIDUAL`) read as a derivative of 4e11 and every standard error collapsed (B 0.3033 +-
    1.3e-11 N mm^2, m 0.6 +- 5.4e-9 on a probe's four specimens of two yarns).

    A step whose point holds a fail residual that the solution does not (an inadmissible cell, a row after a
    failed increment) is no derivative: it is taken the other way, then 10 times smaller either way, within the
    bounds.  Where every try fails the variable's derivative is not known, and so is the covariance: NaN
    throughout (``unknown``: a list that gets such variables' labels), not a number read off fail residuals.

    With offsets on, the rows are those less each specimen's best offset (projected out in closed form):
    the Jacobian of these projected rows gives, by variable projection (Golub and Pereyra), the covariance
    of the variables marginal over the offsets, the same block as the full fit with the offsets as
    variables.  ``offset_gradient``: a list that gets the array [specimens, k] of d offset / d variable (the
    offsets' share of the variables' uncertainty, :func:`_offset_std_errors`); ``zero_gradient``: one that gets
    the array [specimens, k] of d (model force at grip strain 0) / d variable (:func:`_zero_std_errors`)."""
    names, y, los, his = _reported(problem, x)
    k = len(y)
    lo, hi = problem.lo, problem.hi
    # the fit variables of the reported values: x itself but where the map is singular (at m = 0 any fraction of
    # the cone is phi0 = 0: the fraction 0, so that m's step holds phi0 as the reported variables do)
    x = np.clip(_fit_variables(problem, x, names, y), lo, hi)
    h = rel_step * np.maximum(np.abs(x), 1.0)
    h = np.where(x + h > hi, -h, h)
    pts = [x] + [x + h[j] * np.eye(k)[j] for j in range(k)]
    offs: list = []
    zs: list = []
    failed: list = []
    res = problem.evaluate_points(pts, offs, zs, failed)
    clean = [bool(np.array_equal(failed[j + 1], failed[0])) for j in range(k)]
    tries = [(j, t) for j in range(k) if not clean[j] for t in (-h[j], h[j] / 10.0, -h[j] / 10.0)
             if lo[j] <= x[j] + t <= hi[j]]
    if tries:
        o2: list = []
        z2: list = []
        f2: list = []
        r2 = problem.evaluate_points([x + t * np.eye(k)[j] for j, t in tries], o2, z2, f2)
        for (j, t), r, o, z, f in zip(tries, r2, o2, z2, f2):
            if not clean[j] and np.array_equal(f, failed[0]):
                res[j + 1], offs[j + 1], zs[j + 1], h[j], clean[j] = r, o, z, t, True
    J = np.stack([(res[j + 1] - res[0]) / h[j] for j in range(k)], axis=1)
    # the chain rule to the reported variables: dx/dy, column j the fit variables' change with reported variable j
    hy = rel_step * np.maximum(np.abs(y), 1e-3)
    dxdy = np.stack([(_fit_variables(problem, x, names, y + hy[j] * np.eye(k)[j])
                      - _fit_variables(problem, x, names, y - hy[j] * np.eye(k)[j])) / (2.0 * hy[j])
                     for j in range(k)], axis=1)
    J = J @ dxdy
    if offset_gradient is not None:
        o = np.asarray(offs, float)                       # [points, specimens]
        offset_gradient.append(((o[1:] - o[0]) / h[:, None]).T @ dxdy)
    if zero_gradient is not None:
        z = np.asarray(zs, float)                         # [points, specimens]
        zero_gradient.append(((z[1:] - z[0]) / h[:, None]).T @ dxdy)
    info = _row_information(problem, res[0])
    if information is not None:
        information.extend(info)
    if not all(clean):
        if unknown is not None:
            unknown.extend(v.name if v.specimen is None else f"{v.name}[{problem.sp[v.specimen].name}]"
                           for v, ok in zip(problem.vars, clean) if not ok)
        if offset_gradient is not None:
            offset_gradient[-1] = np.full_like(offset_gradient[-1], np.nan)
        if zero_gradient is not None:
            zero_gradient[-1] = np.full_like(zero_gradient[-1], np.nan)
        return np.full((k, k), np.nan)
    rows = np.repeat(info, [len(s.strain) for s in problem.sp])     # each specimen's rows, in their order
    w = np.concatenate([rows, np.ones(len(res[0]) - len(rows))])      # the priors' rows after them weigh 1
    return weighted_covariance(J, w, s2)


def weighted_covariance(J: np.ndarray, w: np.ndarray, s2: float) -> np.ndarray:
    """``s2 (J^T diag(w) J)^-1`` by the capstan and Dahl fits' routine (:func:`knitsim.friction.identification.
    covariance`, the SVD of ``sqrt(w) J``: infinite where it is singular), over the variables the rows move; a
    variable they do not move (a column of ``J`` within 1e-9 of the largest's norm: a jamming width never
    reached) has an infinite variance and no covariance, and leaves the others' as they are.

    Before, the pseudo-inverse of ``J^T W J`` dropped a direction it could not invert: two variables that trade
    exactly (columns proportional) each got a finite standard error, "identified", where the rows set only their
    combination."""
    k = J.shape[1]
    norms = np.linalg.norm(J, axis=0)
    dead = norms <= 1e-9 * max(float(norms.max()) if k else 0.0, 1e-300)
    cov = np.zeros((k, k))
    live = np.flatnonzero(~dead)
    if live.size:
        cov[np.ix_(live, live)] = covariance(np.sqrt(np.asarray(w, float))[:, None] * J[:, live], s2)
    cov[dead, dead] = np.inf
    return cov


def _offset_std_errors(problem: _Problem, fits_bad: list, cov: np.ndarray, G: np.ndarray, s2: float,
                       information: Sequence[float] | None = None) -> list:
    """Standard error of each specimen's fitted offset: the weighted mean's own noise, s2 / sum(1 / sd^2) over
    its rows that count (divided by its rows' information, :func:`_row_information`), plus the variables' share through the offset's dependence on them, g^T cov g (the
    offset's variance in the full fit with the offsets as variables, by block inversion).  A variable the
    rows do not set (infinite variance) moves no offset either: left out."""
    if np.isnan(cov).any():                     # the covariance is not known (:func:`_covariance`): nor are these
        return [math.nan] * len(problem.sp)
    c = np.where(np.isfinite(cov), cov, 0.0)
    out = []
    for k, (s, bad) in enumerate(zip(problem.sp, fits_bad)):
        w2 = np.where(bad, 0.0, 1.0 / s.sigma_N ** 2)
        tot = float(np.sum(w2))
        g = np.nan_to_num(G[k]) if G is not None else np.zeros(len(c))
        q = float(information[k]) if information is not None else 1.0
        var = (s2 / (q * tot) if tot > 0 and q > 0 else math.inf) + float(g @ c @ g)
        out.append(math.sqrt(max(var, 0.0)))
    return out


def _zero_std_errors(cov: np.ndarray, G: np.ndarray | None, n: int) -> list:
    """Standard error of each specimen's model force at grip strain 0 (:attr:`SpecimenFit.pretension_se_N`): the
    delta method, sqrt(g^T cov g), g its gradient over the variables (``G``, [specimens, k]: :func:`_covariance`).
    Infinite where it moves with a variable the rows do not set (infinite variance), or where its gradient is not
    known (a neighbour's cell inadmissible); NaN for every specimen without ``G``.  The rows of the fit start at
    one row step: where they are few, or start past the knit's first slide, the force at rest is an extrapolation
    that they may not determine (a 5-row file up to strain 0.02 fitted within its noise with its knit's force at
    rest 2.6 times the file's reading, and was flagged as a wrong zero)."""
    if G is None:
        return [math.nan] * n
    dead = ~np.isfinite(np.diag(cov))
    c = np.where(np.isfinite(cov), cov, 0.0)
    out = []
    for g in np.asarray(G, float):
        if not np.all(np.isfinite(g)) or np.any(dead & (g != 0.0)):
            out.append(math.inf)
            continue
        out.append(math.sqrt(max(float(g @ c @ g), 0.0)))
    return out


def _zero_costs(pb: _Problem, x: np.ndarray, fits: list, factor: float, refit) -> list:
    """The zero check's statistic for each specimen that reads at rest well below its fitted model
    (:meth:`SpecimenFit._zero_screened`; (NaN, NaN, NaN) for the others): (cost, the model's force at grip
    strain 0 where it is least, the rows' chi2 rise there in s^2).

    The file's reading at rest (``rest_N``, sd ``rest_sd_N``) is not a row of the fit (they start at one row
    step), so whether it disagrees with the model is the cost of it as one more row: the least over the
    variables of the rows' chi2 rise (in the covariance's factor s^2, ``factor``) plus ((model at rest -
    rest_N) / sd)^2, a likelihood ratio.  Sought by a refit from the best point ``x`` with that row added
    (``refit(x0, what)``: the calibration's refinement, bounds and checkpoint, :attr:`_Problem.rest_row`); the
    cost at ``x`` itself, (gap / sd)^2, where that is less.  To first order it is (gap / sqrt(sd^2 + se^2))^2
    (the delta method, se = ``pretension_se_N``), but the model is far from linear there: a probe's three knits
    with W0, C0 and phi0 free read se = 1.5 N at rest (linear), while one standard error along the covariance's
    line cost chi2 2148 s^2; the tared pair of tests/calibration/data one of 0.26 N, and 37 s^2."""
    out = []
    best: tuple | None = None                        # (chi2, model forces at grip strain 0) at x, evaluated once
    for k, f in enumerate(fits):
        if f._zero_screened() is None:
            out.append((math.nan, math.nan, math.nan))
            continue
        gap, sd = f.pretension_N - f.rest_N, f.rest_sd_N
        if not sd > 0:                               # a reading of no noise: no fit makes it but the best's own
            out.append((math.inf, f.pretension_N, 0.0))
            continue
        if best is None:
            zs0: list = []
            best = (float(np.sum(pb.evaluate_points([x], None, zs0)[0] ** 2)), zs0[0])
        chi0 = best[0]
        # the specimen's own run's force at rest (pretension_N) moves as the fit's program's (at_grip_zero)
        shift = f.pretension_N - best[1][k]
        pb.rest_row = (k, f.rest_N - shift, sd)
        try:
            sol = refit(x, f"zero check of {f.name}")
        finally:
            pb.rest_row = None
        zs: list = []
        rise = (float(np.sum(pb.evaluate_points([sol.x], None, zs)[0] ** 2)) - chi0) / factor
        at = zs[0][k] + shift
        cost = rise + ((at - f.rest_N) / sd) ** 2
        out.append(min((cost, at, rise), ((gap / sd) ** 2, f.pretension_N, 0.0),
                       key=lambda c: c[0] if math.isfinite(c[0]) else math.inf))
    return out


_BOUND_NOTES = {
    ("in_plane_width", "high"): "W0/4 of the narrowest knit: its loops jam at rest",
    ("d", "high"): "W0/4 of the narrowest knit: W0 >= 4 d",
    ("in_plane_width", "low"): "the compact diameter d: a round yarn",
    ("phi0", "high"): "+phimax: the knit starts sliding in the loading direction",
    ("phi0", "low"): "-phimax: the knit starts sliding against the loading",
    ("m", "low"): "no friction at the crossing",
    ("pretension", "low"): "0: the knit at rest at the strain origin (no pretension)",
}


def _force_scale_flag(fit: "SpecimenFit") -> str:
    """A specimen whose readings are on another force scale than its fitted knit (the thresholds of
    :func:`knitsim.diagnosis.diagnose.force_scale_mismatch`): every reading below half the force the knit carries
    at rest (kN read as N), or half of them beyond ten times the most it carries (mN read as N); or its largest
    reading per wale below :data:`BENDING_SCALE_SHARE` B / L^2 of the fitted yarn and knit (kN read as N, met by a
    knit that carries almost nothing); "" otherwise.  A blind probe's specimen in kN under a `load_N` header was
    flagged for its misfit and W0 at its bound, nothing said of the unit."""
    from ..diagnosis.diagnose import SCALE_ABOVE, SCALE_SHARE
    target = np.asarray(fit.target_N, float)
    sim = np.asarray(fit.simulated_N, float)
    if not (len(target) and np.all(np.isfinite(target)) and len(sim)):
        return ""
    top, mid = float(np.max(target)), float(np.median(target))
    rest, most = float(fit.pretension_N), float(np.nanmax(sim))
    what = "per wale" if fit.wales == 1 else "on the specimen"
    if most > 0 and mid > SCALE_ABOVE * most:
        return (f"specimen {fit.name}: half its readings exceed {mid:.3g} N {what}, {mid / most:.3g} times the most "
                f"the fitted knit carries ({most:.3g} N): a force in another unit (mN read as N)? Check the column's "
                "unit (and the specimen's width) before anything else")
    if rest > 0 and top < SCALE_SHARE * rest:
        return (f"specimen {fit.name}: every reading (the largest {top:.3g} N {what}) is below the force the fitted "
                f"knit carries at rest ({rest:.3g} N, {rest / max(top, 1e-300):.3g} times more): a force in another "
                "unit (kN read as N)? Check the column's unit (and the specimen's width) before anything else")
    # the fit can also meet such readings with a knit that carries almost nothing (a blind probe's kN file
    # beside one in N: fitted within its noise, the knit at rest at 1e-5 N per wale): the yarn's own force scale
    bend = float(fit.params.B) / float(fit.params.L) ** 2
    per_wale = top / fit.wales if fit.wales > 0 else top
    if bend > 0 and per_wale < BENDING_SCALE_SHARE * bend:
        return (f"specimen {fit.name}: its largest reading, {per_wale:.3g} N per wale, is {per_wale / bend:.2g} x "
                f"B / L^2 of the fitted yarn and knit ({bend:.3g} N, the force that bends the yarn over its loop "
                f"length; a knit pulled through a test carries tens to thousands of times it, flagged below "
                f"{BENDING_SCALE_SHARE:g}): a force in another unit (kN read as N)? Check the column's unit (and the "
                "specimen's width) before anything else")
    return ""


def _unidentified(e: "Estimate") -> str:
    """Why estimate ``e`` is not identified (its rule), or ``""`` where the rows set it."""
    if e.not_identified or e.at_bound == "not identified":
        return e.not_identified or e.bound_note or "its standard error is not finite"
    return ""


def _stated_end(name: str, side: str, bounds, end: float | None) -> bool:
    """Whether the bound ``side`` that variable ``name`` reached is the scene's own ``calibration.bounds.NAME``
    (``bounds``: its [low, high]) rather than the variable's natural end that :data:`_BOUND_NOTES` or the
    geometry's 4 sd explain (m = 0, phi0 = +-phimax, pretension 0, the in-plane width at d: ``end`` is the
    reported bound, max(d, low)).  A probe's m bounded to [0.3, 1] and ending at 0.3 read "no friction at the
    crossing"."""
    u = float(bounds[0] if side == "low" else bounds[1])
    if name in GEOMETRY:
        return True                         # the stated factors replace the 4 sd
    if name in ("m", "pretension"):
        return side == "high" or u > 0.0
    if name == "phi0":
        return abs(u) < 1.0                 # a fraction of phimax
    if name in ("in_plane_width", "d") and end is not None:
        return abs(float(end) - u) <= 1e-9 * max(abs(u), 1e-300)
    return True


def _note(name: str, side: str, specimen: str | None, effect_var=None, stated: bool = True, bounds=None,
          end: float | None = None) -> str:
    """What the bound ``side`` of variable ``name`` means.  An effect's variable (``effect_var``,
    :class:`knitsim.diagnosis.effects.Variable`) whose range the scene did not state (``stated`` False) ends at
    its search's own ends: one where the effect vanishes (a blind probe's compaction_k at 0 on curves without
    compaction read "the low end of the stated range", though none was stated), the others beyond which lies
    more of it (``Variable.more``).  A bound the scene stated (``bounds``, its [low, high]; ``end``, the bound
    reported) is said as such where it is not the variable's natural end (:func:`_stated_end`)."""
    if bounds is not None and _stated_end(name, side, bounds, end):
        return f"the {side} end of the stated range"
    if (name, side) in _BOUND_NOTES:
        return _BOUND_NOTES[(name, side)]
    if name in GEOMETRY:
        return f"4 sd of its stated value ({'below' if side == 'low' else 'above'}): the measurement does not allow more"
    if effect_var is not None and not stated:
        end = "lower" if side == "low" else "upper"
        if end in effect_var.more:
            return (f"the {side} end of its search, beyond which lies more of the effect: state a wider "
                    f"calibration.bounds.{name}")
        if effect_var.more:       # (the other end of a one-sided effect: where it vanishes)
            return (f"the {side} end of its search, where the effect vanishes: the rows show none of it (calibrate "
                    "without the effect)")
        return f"the {side} end of its search"
    return f"the {side} end of the stated range"


def identification_rule(std_error: float, low: float, high: float, unit: str = "", unknown: str = "") -> str:
    """Why an estimate is not identified, or ``""`` when it is: its standard error is not known (NaN: no
    derivative could be taken, :func:`_covariance`; ``unknown`` names the variables whose steps failed), not
    finite (the rows do not depend on it), or larger than :data:`NOT_IDENTIFIED_SHARE` (half) of its range
    ``high - low`` (any value in the range fits as well).  All in the estimate's unit."""
    u = f" {unit}" if unit else ""
    if math.isnan(std_error):
        return ("its standard error is not known: " + (f"{unknown}'s" if unknown else "a variable's")
                + " finite-difference step, either way and 10 times smaller, made a cell inadmissible or a row fail "
                "where the best point's do not, so the rows' derivative there (and the covariance) is not known")
    if not math.isfinite(std_error):
        return "its standard error is not finite: the rows do not depend on it"
    if std_error > NOT_IDENTIFIED_SHARE * (high - low):
        return (f"its standard error {std_error:.4g}{u} is larger than half its range {low:.4g} .. {high:.4g}{u}: "
                "any value in the range fits as well")
    return ""


def rival_spread(value: float, std_error: float, rivals: Sequence[tuple[float, float]]) -> float:
    """How far from ``value`` another refined start fits as well (``rivals``: each its chi2 above the best's, in
    units of s^2, and its value): the largest distance of a rival within :data:`RIVAL_DCHI2` that lies beyond
    :data:`RIVAL_SE` standard errors; 0 where none does.  The standard error is the curvature at the best point;
    with a quadratic chi2 a point k standard errors away costs k^2 s^2 more, so an equal fit further away means a
    flat or many-valleyed direction."""
    if not (math.isfinite(std_error) and math.isfinite(value)):
        return 0.0
    far = [abs(v - value) for d, v in rivals
           if d <= RIVAL_DCHI2 and math.isfinite(v) and abs(v - value) > RIVAL_SE * std_error]
    return max(far, default=0.0)


#: what a profile probe is, in :func:`rival_rule`'s text
PROBE_WHAT = f"the best point with this variable {PROBE_SE:g} standard errors out, the others held,"


def rival_rule(value: float, std_error: float, rivals: Sequence[tuple[float, float]], unit: str = "",
               tolerance: float = 0.0, what: str = "another refined start") -> str:
    """Why an estimate is not identified though its standard error is finite, or ``""``: another refined start
    fits as well at a value further than :data:`RIVAL_SE` standard errors (:func:`rival_spread`) and further than
    ``tolerance`` (a knit's stated sd, its prior: a geometry the rows leave open within what the lab measured is
    known as well as the lab knows it).  (A blind probe's knit that never jams: in_plane_width 0.823 +- 0.0036
    mm, no flag, while starts ended at 0.709 .. 0.803 within 0.2 of its chi2 43.1, the truth 0.79.)  ``what``
    names the rivals in the text (the profile's probes: :data:`PROBE_WHAT`)."""
    spread = rival_spread(value, std_error, rivals)
    if not spread > tolerance:
        return ""
    u = f" {unit}" if unit else ""
    near = [v for d, v in rivals if d <= RIVAL_DCHI2 and math.isfinite(v)]
    lo, hi = min(near + [value]), max(near + [value])
    k = spread / std_error if std_error > 0 else math.inf
    return (f"{what} fits as well (chi2 within {RIVAL_DCHI2:g} max(s^2, 1) of the best) {spread:.4g}{u} "
            f"away, {k:.3g} of the best point's standard errors ({std_error:.4g}{u}): {lo:.4g} .. {hi:.4g}{u} fit "
            "alike")


def check_setup(specimens: Sequence[SpecimenData], setup: JointSetup) -> None:
    """Every check :func:`calibrate_joint` makes before its first solve (the variables, bounds, priors, the
    rows' grid, strains the knits cannot reach), without solving: a scene is refused before any work.

    Raises
    ------
    KnitsimInputError
    """
    _Problem(specimens, setup)


class CalibrationInterrupted(Exception):
    """The fit stopped early (``stop_after`` evaluations); its checkpoint holds the work done."""

    def __init__(self, done: int, path):
        super().__init__(f"stopped after {done} evaluations; checkpoint {path}")
        self.done, self.path = done, path


def fingerprint(specimens: Sequence[SpecimenData], setup: JointSetup) -> str:
    """Hash of everything that determines a calibration (its rows, weights, knits and setup): checked on resume."""
    import hashlib
    h = hashlib.sha256(repr(setup).encode())
    for sp in specimens:
        h.update(repr((sp.name, sp.total, sp.width_mm, sp.gauge_length_mm, sorted(sp.knit.items()),
                       sorted(sp.uncertainty.items()), sp.pretension, sp.pretension_sd)).encode())
        for a in (sp.strain, sp.target_N, sp.sigma_N, sp.band_low_N, sp.band_high_N):
            h.update(b"-" if a is None else np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()


@dataclass
class _Refined:
    """What a finished refinement leaves (the fields of scipy's OptimizeResult that are used)."""

    x: np.ndarray
    cost: float
    nfev: int
    success: bool
    message: str


def _pretensioned_rows(cell: CellParams, s: SpecimenData, pretension: float, max_increment: float,
                       device: str) -> tuple[np.ndarray, np.ndarray, float]:
    """Force per wale and status at a pretensioned specimen's rows, and its force at grip strain 0:
    the cell on the program its patch scene runs (:func:`knitsim.cell.load_program.pretensioned`,
    a uniform specimen's knit strain is (1 + pretension) x the solver's grip strain)."""
    offset = pretension / (1.0 + pretension)
    grip = pretensioned(monotonic(float(s.strain[-1]), max_increment), offset, max_increment)
    knit = LoadProgram(grip.strain * (1.0 + pretension), grip.cycle, grip.direction,
                       tuple(w * (1.0 + pretension) for w in grip.waypoints))
    h = run_batch([cell], knit, device=device)
    at = grip.strain - offset
    rows = np.minimum(np.searchsorted(at, s.strain - 1e-9), len(at) - 1)
    if not np.allclose(at[rows], s.strain, rtol=0.0, atol=1e-9):
        # rows off the increments (row_step not a multiple of max_increment): read between them
        F = np.interp(s.strain, np.concatenate(([-offset], at)), np.concatenate(([0.0], h.force_per_wale[:, 0])))
    else:
        F = h.force_per_wale[rows, 0]
    worst = np.maximum.accumulate(h.status[:, 0])
    i0 = int(np.argmin(np.abs(at)))
    return F, worst[rows], float(h.force_per_wale[i0, 0])


def calibrate_joint(specimens: Sequence[SpecimenData], setup: JointSetup,
                    progress: Callable[[str], None] | None = None,
                    counter: Callable[[str, int], Callable[[int], None]] | None = None,
                    checkpoint=None, resume: bool = False, stop_after: int | None = None) -> JointResult:
    """Fit one yarn to several specimens (module docstring).

    Parameters
    ----------
    specimens : sequence of SpecimenData
        On one uniform grid of rows (one ``row_step``).
    setup : JointSetup
    progress : callable, optional
        ``progress(line)`` at each stage (starts screened, each start refined).
    counter : callable, optional
        ``counter(what, total)`` returns ``tick(done)``, called as the work of a stage gets done: the
        starts screened (``total`` of them), then each refined start's evaluations (at most
        ``max_nfev``; its ``tick(total)`` when it ends earlier).  A progress bar
        (:class:`knitsim.cli.common.Progress`).
    checkpoint : path, optional
        File that keeps the finished work: the screened starts' chi2, every finished refinement, and
        the evaluations (residuals and Jacobian) of the refinement under way; written after every
        screening chunk and refinement, every 10 s of evaluations, and on Ctrl-C.
    resume : bool
        Continue from ``checkpoint``: finished work is not redone, and an interrupted refinement
        replays its saved evaluations (least squares is deterministic), so the result is the one
        of an uninterrupted fit.  A checkpoint of other specimens or another setup is refused.
    stop_after : int, optional
        Stop (with a checkpoint) after this many new evaluations: raises :class:`CalibrationInterrupted`.

    Returns
    -------
    JointResult

    Raises
    ------
    KnitsimInputError
        A bad setup (unknown variable, a geometry fitted without an uncertainty, bad bounds), or an
        unusable checkpoint, before any solve.
    """
    import pickle
    from pathlib import Path
    t0 = time.perf_counter()
    say = progress or (lambda line: None)
    count = counter or (lambda what, total: (lambda done: None))
    pb = _Problem(specimens, setup)
    ck = None if checkpoint is None else Path(checkpoint)
    fp = fingerprint(specimens, setup)
    state = {"fingerprint": fp, "costs": [], "refined": [], "log": {}, "wall_s": 0.0}     # wall_s: of earlier runs
    if resume:
        if ck is None or not ck.is_file():
            raise KnitsimInputError(f"--resume: no calibration checkpoint {ck} to resume from")
        try:
            saved = pickle.loads(ck.read_bytes())
        except Exception as exc:  # noqa: BLE001 - a damaged file is a user-level problem
            raise KnitsimInputError(f"--resume: {ck} is not a readable checkpoint ({exc})") from None
        if not isinstance(saved, dict) or saved.get("fingerprint") != fp:
            raise KnitsimInputError(f"--resume: {ck} belongs to other specimens or another calibration setup; "
                                    "remove it or run without --resume")
        state = saved
        say(f"resumed: {len(state['costs'])} starts screened, {len(state['refined'])} refined, "
            f"{len(state['log'])} evaluations of the refinement under way")
    wall_before = float(state["wall_s"])
    last_save = [time.perf_counter()]
    new_evals = [0]

    def save():
        if ck is not None:
            from ..io.results import atomic_write_bytes, record_outputs
            state["wall_s"] = wall_before + time.perf_counter() - t0
            record_outputs(ck.parent, [ck.name])     # knitsim's to replace with --overwrite (io.output_dir)
            atomic_write_bytes(ck, pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL))
            last_save[0] = time.perf_counter()

    x_own = pb.start()
    X = [x_own] + _lhs(pb, setup.starts, setup.seed)
    costs = state["costs"]
    chunk = 16
    tick = count("starts screened", len(X))
    tick(len(costs))
    try:
        for a in range(len(costs), len(X), chunk):
            res = pb.evaluate_points(X[a:a + chunk])
            costs += [float(r @ r) for r in res]
            tick(len(costs))
            say(f"screened {min(a + chunk, len(X))}/{len(X)} starts (best chi2 {min(costs):.4g})")
            save()
        order = list(np.argsort(costs, kind="stable")[:max(1, setup.refine)])
        log = state["log"]            # the evaluations of the refinement under way (x bytes -> (r, J))

        def ev(x, problem):
            key = np.asarray(x, float).tobytes()
            if key not in log:
                if stop_after is not None and new_evals[0] >= stop_after:
                    save()
                    raise CalibrationInterrupted(new_evals[0], ck)
                log[key] = problem.evaluate_with_jacobian(x)
                new_evals[0] += 1
                if time.perf_counter() - last_save[0] > 10.0:
                    save()
            tick_ev(len(log))
            return log[key]

        def refine(x0, what, problem=pb, into="refined"):
            nonlocal tick_ev
            tick_ev = count(f"{what}: evaluations", setup.max_nfev)
            r = least_squares(lambda x: ev(x, problem)[0], x0, jac=lambda x: ev(x, problem)[1],
                              bounds=(problem.lo, problem.hi), method="trf", x_scale="jac",
                              max_nfev=setup.max_nfev, ftol=1e-8, xtol=1e-8, gtol=1e-10)
            tick_ev(setup.max_nfev)
            sol = _Refined(np.asarray(r.x, float), float(r.cost), int(r.nfev), bool(r.success), str(r.message))
            state[into].append(sol)
            log.clear()
            save()
            return sol

        tick_ev = None
        best = None
        starts = []
        mids = []
        for rank, i in enumerate(order):
            sol = (state["refined"][rank] if rank < len(state["refined"])
                   else refine(X[i], f"start {rank + 1}/{len(order)}"))
            cost = float(2.0 * sol.cost)
            starts.append({"start": int(i), "objective": pb.objective, "chi2_start": costs[i], "chi2": cost,
                           "nfev": int(sol.nfev), "success": bool(sol.success), "message": str(sol.message)})
            say(f"start {rank + 1}/{len(order)}: chi2 {costs[i]:.4g} -> {cost:.4g} in {sol.nfev} evaluations")
            mids.append((cost, rank, sol))
            if best is None or cost < best[0]:
                best = (cost, sol)
        finals = [(c, s_) for c, _, s_ in mids]     # the last stage's solutions (rivals of the best: rival_rule)
        if setup.objective == "band":
            # stage 2: the band likelihood from each mid-line solution (best first); its steep walls
            # (the force accuracy) make it a poor landscape to start from anywhere else
            pb.objective = "band"
            best = None
            finals = []
            for j, (_, rank, msol) in enumerate(sorted(mids, key=lambda t: (t[0], t[1]))):
                at = len(order) + j
                sol = (state["refined"][at] if at < len(state["refined"])
                       else refine(msol.x, f"band likelihood from start {rank + 1}"))
                r0 = pb.evaluate_points([msol.x])[0]
                c0 = float(r0 @ r0)
                cost = float(2.0 * sol.cost)
                starts.append({"start": int(order[rank]), "objective": "band", "chi2_start": c0, "chi2": cost,
                               "nfev": int(sol.nfev), "success": bool(sol.success), "message": str(sol.message)})
                say(f"band likelihood from start {rank + 1}: chi2 {c0:.4g} -> {cost:.4g} in {sol.nfev} evaluations")
                finals.append((cost, sol))
                if best is None or cost < best[0]:
                    best = (cost, sol)
    except KeyboardInterrupt:
        save()
        raise
    chi2, sol = best
    x = sol.x
    n = pb.n_rows + pb.n_prior
    # degrees of freedom: the rows and priors less the variables and, with offsets on, one offset a specimen
    s2 = chi2 / max(n - pb.k_total, 1)
    # the covariance's factor: scaled up where the rows scatter beyond their sds, never down (a band's half-width,
    # the stated priors: module docstring)
    factor = max(s2, 1.0)
    grads: list = []
    info: list = []
    zero_grads: list = []
    unknown: list = []
    cov = _covariance(pb, x, factor, offset_gradient=grads, information=info, zero_gradient=zero_grads,
                      unknown=unknown)
    names, y, los, his = _reported(pb, x)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(np.where(np.isfinite(se), se, np.nan), np.where(np.isfinite(se), se, np.nan))
    corr = np.where(np.isfinite(corr) | np.isnan(cov), corr, 0.0)     # NaN where the covariance is not known
    np.fill_diagonal(corr, 1.0)
    estimates = []
    lo_f, hi_f = pb.lo, pb.hi
    # the other refined starts: each one's chi2 above the best's (in s^2) and its reported values
    rivals = [((c - chi2) / factor, _reported(pb, r.x)[1]) for c, r in finals if r is not sol]
    # and the best point with each variable moved 4 standard errors: starts that fall into one valley see no rival (a
    # blind probe's loose knit with the default refine = 3: w 6.5 standard errors off the truth and no flag)
    probes = _profile_probes(pb, x, cov, chi2, factor)
    for j, ((nme, spi), val) in enumerate(zip(names, y)):
        span = hi_f[j] - lo_f[j]
        side = "low" if x[j] - lo_f[j] <= BOUND_TOL * span else ("high" if hi_f[j] - x[j] <= BOUND_TOL * span else None)
        spname = None if spi is None else pb.sp[spi].name
        stated, dev = pb.prior_pull(nme, spi, x[j])
        unit = UNITS.get(nme, pb.effect_vars[nme].unit if nme in pb.effect_vars else "")
        note = (_note(nme, side, spname, pb.effect_vars.get(nme), nme in pb.user_bounds, pb.user_bounds.get(nme),
                      float(los[j] if side == "low" else his[j])) if side else "")
        if side == "high" and nme in ("d", "in_plane_width") and nme in pb.user_bounds \
                and his[j] >= pb.user_bounds[nme][1] * (1 - 1e-12):
            note = "the high end of the stated range (below W0/4 of the narrowest knit)"
        # values another refined start reaches as well widen the standard error to theirs (1.96 sd: 95 %)
        mine = [(d, float(v[j])) for d, v in rivals]
        probed = [(d, float(v[j])) for d, v in probes]
        se_j = max(float(se[j]), rival_spread(float(val), float(se[j]), mine + probed) / 1.96)
        unid = identification_rule(se_j, float(los[j]), float(his[j]), unit, ", ".join(unknown))
        prior = (float(stated * pb.sp[spi].uncertainty[nme]) if nme in GEOMETRY else
                 float(pb.sp[spi].pretension_sd) if nme == "pretension" else 0.0)
        rival = "" if unid else (rival_rule(float(val), float(se[j]), mine, unit, tolerance=prior)
                                 or rival_rule(float(val), float(se[j]), probed, unit, tolerance=prior,
                                               what=PROBE_WHAT))
        if unid or rival:
            side = side or "not identified"
            note = (note + "; " if note else "") + ("its standard error is not known (not identified)"
                                                    if np.isnan(se[j]) else
                                                    "the rows do not depend on it (not identified)"
                                                    if not np.isfinite(se[j]) else
                                                    "another start fits as well far away (not identified)" if rival
                                                    else "standard error above half its range (not identified)")
        unid = unid or rival
        estimates.append(Estimate(nme, spname, float(val), se_j, unit, float(los[j]), float(his[j]), side,
                                  note, stated, dev, unid))
    # each specimen's fit
    cells = pb.cells_at(x)
    sims = pb.simulate(list(enumerate(cells)))
    _, own_x = pb.model_values(x)
    fits = []
    fits_bad = []
    all_ok = True
    for k, s in enumerate(pb.sp):
        c = cells[k]
        if c is None:                      # pragma: no cover - the best point of a fit is admissible
            raise RuntimeError(f"specimen {s.name}: the calibrated point is not an admissible cell")
        w = s.wales(c.W0) if s.total else 1.0
        e_p = float(own_x[k].get("pretension", s.pretension))
        # the force at grip strain 0: the knit's rest state without a pretension (a blind probe read 0 N in the
        # report where the calibrated cell carries 0.0136 N per wale at rest)
        pre_N = w * rest_force_per_wale(c)
        if pb.pretension and e_p > 0:
            # the fit read its rows between increments; the reported curve is the specimen's own run,
            # as its written patch scene runs it: from rest through the pretension, then the rows
            f, st, pre_f = _pretensioned_rows(c, s, e_p, setup.max_increment, setup.device)
            pre_N = w * pre_f             # the force at grip strain 0: the pretension the model implies
        else:
            f, st = pb.at_rows(k, sims[k], own_x[k])
        # tared: what the fit subtracted (the batch's rest state; with a pretension, its program read at the
        # pretension strain, linearly from the rest state below the first increment: coarse where the knit
        # stiffens within it, so it may differ from pre_N, the specimen's own run)
        tare = w * pb.at_zero(k, sims[k], own_x[k])
        sim = w * f
        worst = int(np.max(st))
        all_ok &= worst == STATUS_OK
        bad = np.maximum.accumulate(np.asarray(st) != STATUS_OK)
        fits_bad.append(bad)
        # the rows are fitted by the model plus its offset (0 with offsets off: the numbers of before)
        off = pb.offset(s, sim, bad)
        fitted = sim + off if pb.offsets else (sim - tare if pb.tared else sim)
        e = fitted - s.target_N
        rms = float(np.sqrt(np.mean(e * e)))
        frac = float(np.mean(s.in_band(fitted))) if s.has_band else None
        frac_tol = float(np.mean(s.in_band_tolerant(fitted))) if s.has_band else None
        res = s.band_residuals(fitted) if setup.objective == "band" else e / s.sigma_N
        fits.append(SpecimenFit(s.name, c, w, s.strain, s.target_N, sim, s.sigma_N, s.band_low_N, s.band_high_N,
                                frac, rms, rms / float(np.sqrt(np.mean(s.target_N ** 2))),
                                float(np.sum(res ** 2)), STATUS_NAMES[worst], e_p, pre_N, frac_tol, res,
                                setup.objective, off if pb.offsets else None, math.nan,
                                "N (total)" if s.total else "N per wale", pb.zero,
                                float(tare) if pb.tared else None, float(getattr(s, "rest_N", math.nan)),
                                float(getattr(s, "rest_sd_N", math.nan))))
    if pb.offsets:
        ses = _offset_std_errors(pb, fits_bad, cov, grads[0] if grads else None, factor, info)
        fits = [replace(f, offset_se_N=float(se_k)) for f, se_k in zip(fits, ses)]
    # the standard error of each model's force at grip strain 0: what the zero check reads the gap against
    zses = _zero_std_errors(cov, zero_grads[0] if zero_grads else None, len(fits))
    fits = [replace(f, pretension_se_N=float(se_k)) for f, se_k in zip(fits, zses)]
    if pb.zero == "absolute":
        zero_done = state.setdefault("zero_check", [])
        refits = [0]

        def zero_refine(x0, what):
            i = refits[0]
            refits[0] += 1
            return zero_done[i] if i < len(zero_done) else refine(x0, what, pb, "zero_check")
        try:
            costs = _zero_costs(pb, x, fits, factor, zero_refine)
        except KeyboardInterrupt:
            save()
            raise
        fits = [replace(f, zero_cost=float(q), zero_witness_N=float(z), zero_witness_dchi2=float(dc))
                for f, (q, z, dc) in zip(fits, costs)]
    # do the specimens look like one yarn? each refitted with its own yarn (checkpointed like the fit)
    own_done = state.setdefault("one_yarn", [])

    def own_refine(x0, what, problem, k):
        return own_done[k] if k < len(own_done) else refine(x0, what, problem, "one_yarn")
    # the check's F test reads the drop of chi2 against the residual variance of Gaussian rows (of any scale); the
    # band likelihood's cost is no such variance (a box: 0 anywhere inside the band, whatever the scatter, so its
    # "residual variance" is the few rows near an edge, and one yarn on a +-4 % band read p = 7e-32): under the band
    # objective it tests the mid-line fit the band likelihood started from (the best), a Gaussian fit of the same rows
    x_check, conv_check = x, bool(sol.success)
    if setup.objective == "band":
        _, _, msol = min(mids, key=lambda t: (t[0], t[1]))
        x_check, conv_check = msol.x, bool(msol.success)
        pb.objective = "midline"
    try:
        check = _one_yarn_check(pb, x_check, own_refine, say, conv_check, all_ok)
    except KeyboardInterrupt:
        save()
        raise
    finally:
        pb.objective = setup.objective
    msg = str(sol.message) + ("" if all_ok else "; a specimen's cell did not solve on every row")
    return JointResult(estimates, corr, fits, chi2, n, pb.k_total, s2, bool(sol.success) and all_ok, msg, starts,
                       int(sol.nfev), wall_before + time.perf_counter() - t0,
                       setup, cells[0], bool(sol.success), str(sol.message), check, factor,
                       {s.name: q for s, q in zip(pb.sp, info)})


def _one_yarn_check(pb: _Problem, x: np.ndarray, refine, say, converged: bool, cells_ok: bool) -> OneYarnCheck:
    """Do the specimens look like one yarn?  (:class:`OneYarnCheck`.)

    Each specimen is refitted alone with every shared variable its own (its knit, phi0, pretension and
    priors as in the joint fit), from the joint solution: its rows and priors then cost ``chi2_own_k <=
    chi2_joint_k``.  The drop ``D = sum_k (chi2_joint_k - chi2_own_k)`` is the likelihood ratio of one
    yarn against a yarn per specimen, ``dof = len(shared) (S - 1)`` variables more; read against the
    residual variance of the larger model (an F test: Chow's test), ``F = (D / dof) / (chi2_own / (n - k -
    dof))``, flagged where its upper tail ``p < ONE_YARN_P``.  A refinement that stops early leaves ``D``
    smaller (the test conservative); the geometry priors let a specimen's own yarn trade with its knit, so
    fewer than ``dof`` directions are free and the test is conservative again.

    The rows are read under ``pb.objective``, which must be a Gaussian one (the mid-line: ``x`` is then the
    mid-line solution under the band objective, :func:`calibrate_joint`): the F test's denominator is the residual
    variance, and a box likelihood's cost is none (inside the band it is 0, whatever the scatter).  That variance is
    taken at 1 where it is below (the rows scatter less than their stated sds): the priors' terms have scale 1 by
    construction, and a drop of the knits' prior cost read against the rows' smaller scatter would flag one yarn
    (sds are scaled up, never down, as the Birge ratio is).

    ``refine(x0, what, problem, k)`` refines specimen ``k``'s problem from ``x0`` (the calibration's own,
    checkpointed); ``say`` reports progress.
    """
    from scipy.stats import f as f_dist
    t0 = time.perf_counter()
    names = tuple(s.name for s in pb.sp)
    shared = tuple(pb.shared)
    # the per-specimen prior furthest from its stated value at x (as the estimates read it: x / prior sd)
    pulls = []
    for v, xi in zip(pb.vars, x):
        stated, dev = pb.prior_pull(v.name, v.specimen, xi)
        if dev is not None:
            pulls.append((f"{v.name}[{pb.sp[v.specimen].name}]", dev, stated, UNITS.get(v.name, "")))
    top = max(pulls, key=lambda t: abs(t[1]), default=None)
    base = {"specimens": names, "shared": shared, "largest_pull": top, "objective": pb.setup.objective}

    def skipped(why):
        return OneYarnCheck(False, why, **base)
    if len(pb.sp) < 2:
        return skipped("one specimen: nothing to compare it with")
    if not shared:
        return skipped("nothing is shared: each specimen already has its own yarn")
    if not converged:
        return skipped("the fit did not converge: its chi2 is not its minimum, so a drop from it does not measure "
                       "how far the specimens are from one yarn")
    if not cells_ok:
        return skipped("a specimen's cell did not solve on every row")
    q = len(shared) * (len(pb.sp) - 1)
    # k_total: the variables and, with offsets on, each specimen's offset (in both models: not in q)
    dof_resid = pb.n_rows + pb.n_prior - pb.k_total - q
    if dof_resid <= 0:
        return skipped(f"too few rows: {pb.n_rows + pb.n_prior} rows and priors for {pb.k_total + q} parameters "
                       "of a yarn per specimen" + (" (force offsets included)" if pb.offsets else ""))
    problems = []
    for s in pb.sp:
        try:
            problems.append(_Problem([s], pb.setup))
        except KnitsimInputError as exc:
            return skipped(f"specimen {s.name} cannot be fitted with a yarn of its own ({exc})")
    shared_v, own_v = pb.model_values(x)
    idx = {(v.name, v.specimen): j for j, v in enumerate(pb.vars)}
    joint_each, own_each, yarns, conv, nfev = [], [], [], [], 0
    for k, (s, pk) in enumerate(zip(pb.sp, problems)):
        pk.objective = pb.objective
        x0 = []
        for v in pk.vars:                 # the joint solution in this specimen's variables
            xi = x[idx[(v.name, None if v.specimen is None else k)]]
            if v.name == "d":             # fractions of ranges that depend on the narrowest knit: its own here
                lo, hi = pk.d_range([own_v[k]["W0"]])
                xi = (shared_v["d"] - lo) / (hi - lo) if hi > lo else 0.0
            elif v.name == "in_plane_width":
                lo, hi = pk.w_range(shared_v.get("d", pk.base.d), [own_v[k]["W0"]])
                xi = (shared_v["in_plane_width"] - lo) / (hi - lo) if hi > lo else 0.0
            x0.append(xi)
        x0 = np.clip(np.array(x0, float), pk.lo, pk.hi)
        r0 = pk.evaluate_points([x0])[0]
        c0 = float(r0 @ r0)
        sol = refine(x0, f"one-yarn check: {s.name} with a yarn of its own", pk, k)
        c1 = min(c0, 2.0 * sol.cost)
        xs = sol.x if 2.0 * sol.cost <= c0 else x0
        say(f"one-yarn check: {s.name} with a yarn of its own: chi2 {c0:.4g} -> {c1:.4g} in {sol.nfev} evaluations")
        own_shared, _ = pk.model_values(xs)
        joint_each.append(c0)
        own_each.append(c1)
        yarns.append({n: float(own_shared[n]) for n in shared})
        conv.append(bool(sol.success))
        nfev += int(sol.nfev)
    drop = max(0.0, sum(joint_each) - sum(own_each))
    # the residual variance, never below the stated sds' 1: the priors' terms have that scale by construction,
    # and rows that scatter less than their stated sd (a band's half-width, the specimens' scatter, around a
    # mid-line that scatters less) would read the priors' drop as a difference of yarns (one yarn on +-4 % bands
    # of stated knits 0.5 prior sd off: p = 2e-18, the drop the knits' priors'); sds are scaled up, not down
    resid = max(sum(own_each) / dof_resid, 1.0)
    F = (drop / q) / resid if resid > 0 else (math.inf if drop > 0 else 0.0)
    p = float(f_dist.sf(F, q, dof_resid)) if math.isfinite(F) else 0.0
    units = {n: UNITS.get(n, pb.effect_vars[n].unit if n in pb.effect_vars else "") for n in shared}
    return OneYarnCheck(True, "", names, shared, float(sum(joint_each)), tuple(joint_each), tuple(own_each), q,
                        dof_resid, float(F), p, tuple(yarns), units, tuple(conv), nfev, time.perf_counter() - t0,
                        base["largest_pull"], objective=pb.setup.objective)


__all__ = ["rival_rule", "rival_spread", "CalibrationInterrupted", "check_setup", "check_zero", "ZERO_MODES", "ZERO_CHECK_SD", "ZERO_CHECK_SHARE", "OneYarnCheck", "ONE_YARN_P", "identification_rule", "NOT_IDENTIFIED_SHARE", "fingerprint", "JointSetup", "Estimate", "SpecimenFit", "JointResult", "calibrate_joint", "YARN_VARIABLES",
           "SPECIMEN_VARIABLES", "UNITS", "OBJECTIVES"]
