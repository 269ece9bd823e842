"""Specimens of a calibration: a knit between grips, and what was measured on it.

A tester reports, per specimen, the force on the whole specimen against the
grip strain (grip displacement / gauge length), often only as the upper and
lower envelopes of the scatter of several tests; the knit is known by its
loop length L and, with less certainty, its wale and course spacings W0, C0
(measured or estimated, e.g. from Munden's constants).  :class:`SpecimenData`
holds that, on the rows the fit uses:

- the rows are a uniform grid of grip strains from one step to the end of the
  data (the smaller of the envelopes' last strains), so that a share of rows
  is a share of the strain range;
- the target is the measured curve there (linear interpolation) when one is
  given, else the mid-line of the envelopes;
- each row's weight is 1 / its sd: the half-width of the envelope band (the
  band is the tolerance a fit must meet), but not below the accuracy of the
  testing machine's force, ``accuracy_rel`` of the reading (0.5 %: ISO 7500-1
  class 0.5; two envelopes that cross leave no width there, though the
  specimens scatter and the machine reads no better); for a curve without a
  band, its noise (given, or estimated from the curve,
  :mod:`knitsim.diagnosis.noise`).

Files: CSV (``,`` ``;`` or tab, :mod:`knitsim.io.table_input`) with a strain
column (``strain`` or ``strain_mm_per_mm``) and a force column, the total
force (``load_N`` or ``force_N``) or the force per wale
(``force_per_wale_N``).  Units N and mm; strain dimensionless.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import KnitsimInputError
from ..io.table_input import read_csv_columns

STRAIN_COLUMNS = ("strain", "strain_mm_per_mm")
TOTAL_COLUMNS = ("load_N", "force_N")
PER_WALE_COLUMNS = ("force_per_wale_N",)
#: knit geometry a specimen states (mm), and may let the fit move within its uncertainty
GEOMETRY = ("L", "W0", "C0")
#: relative accuracy of a tensile tester's force reading (ISO 7500-1 class 0.5): the least sd of a band's row
FORCE_ACCURACY_REL = 0.005


@dataclass(frozen=True)
class MeasuredTable:
    """One file: strain [-] and force [N], total or per wale, with its spreadsheet rows."""

    strain: np.ndarray
    force: np.ndarray
    total: bool
    source: str
    rows: np.ndarray


def read_table(path: str | Path) -> MeasuredTable:
    """Read a strain-force file (module docstring); refuses what is wrong, naming file, row and column."""
    path = Path(path)
    cols = read_csv_columns(path, (), STRAIN_COLUMNS + TOTAL_COLUMNS + PER_WALE_COLUMNS)
    s_name = next((c for c in STRAIN_COLUMNS if c in cols), None)
    f_total = next((c for c in TOTAL_COLUMNS if c in cols), None)
    f_wale = next((c for c in PER_WALE_COLUMNS if c in cols), None)
    if s_name is None:
        raise KnitsimInputError(f"{path}: no strain column (expected one of {', '.join(STRAIN_COLUMNS)})")
    if f_total is None and f_wale is None:
        raise KnitsimInputError(f"{path}: no force column (expected the total force {' or '.join(TOTAL_COLUMNS)}, "
                                f"or {PER_WALE_COLUMNS[0]})")
    if f_total is not None and f_wale is not None:
        raise KnitsimInputError(f"{path}: both a total force ({f_total}) and a force per wale ({f_wale}): "
                                "keep one column")
    strain, rows = cols[s_name], cols["_row"]
    force = cols[f_total or f_wale]
    bad = np.nonzero(strain < 0)[0]
    if len(bad):
        i = int(bad[0])
        raise KnitsimInputError(f"{path}: row {rows[i]}, column {s_name}: {float(strain[i])!r} is negative (a tensile "
                                "test starts at strain 0)")
    back = np.nonzero(np.diff(strain) < 0)[0]
    if len(back):
        i = int(back[0]) + 1
        raise KnitsimInputError(f"{path}: row {rows[i]}, column {s_name}: {float(strain[i])!r} is below the row before "
                                f"({float(strain[i - 1])!r}); a calibration reads loading curves (strain non-decreasing)")
    if len(strain) < 2 or strain[-1] <= strain[0]:
        raise KnitsimInputError(f"{path}: the strain does not increase (needs a loading curve)")
    return MeasuredTable(np.asarray(strain, float), np.asarray(force, float), f_total is not None, str(path), rows)


def _interp(t: MeasuredTable, x: np.ndarray) -> np.ndarray:
    # repeated strains (a logger writing a row twice) are averaged, so that the interpolation is defined
    s, inv = np.unique(t.strain, return_inverse=True)
    f = np.bincount(inv, weights=t.force) / np.bincount(inv)
    return np.interp(x, s, f)


@dataclass(frozen=True)
class SpecimenData:
    """One specimen on the rows of the fit.

    Attributes
    ----------
    name : str
    strain : ndarray, shape [n]
        Grip strains of the rows (uniform grid).
    target_N : ndarray, shape [n]
        Force to fit [N]: total on the specimen (``total``), or per wale.
    sigma_N : ndarray, shape [n]
        sd of each row [N] (module docstring).
    band_low_N, band_high_N : ndarray, shape [n], or None
        The experimental band at the rows, where given.
    total : bool
        Forces are on the whole specimen (the model's force per wale times width / W0).
    width_mm, gauge_length_mm : float
        Specimen width across the wales and distance between the grips.
    knit : dict
        Stated L, W0, C0 [mm].
    uncertainty : dict
        Relative sd of each stated L, W0, C0 (the prior of a fitted one; 0: known).
    sources : list of str
        The files read.
    sigma_rule : str
        How the sds were obtained (for the report).
    """

    name: str
    strain: np.ndarray
    target_N: np.ndarray
    sigma_N: np.ndarray
    band_low_N: np.ndarray | None
    band_high_N: np.ndarray | None
    total: bool
    width_mm: float
    gauge_length_mm: float
    knit: dict
    uncertainty: dict = field(default_factory=dict)
    sources: tuple = ()
    sigma_rule: str = ""

    @property
    def has_band(self) -> bool:
        return self.band_low_N is not None

    def wales(self, W0: float) -> float:
        """Wales across the specimen at wale spacing ``W0`` [mm] (width / W0)."""
        return self.width_mm / W0

    def in_band(self, force_N: np.ndarray) -> np.ndarray:
        """Whether each row's force lies inside the experimental band (all True without a band)."""
        if not self.has_band:
            return np.ones(len(self.strain), bool)
        return (force_N >= self.band_low_N) & (force_N <= self.band_high_N)


def specimen_from_files(name: str, *, width_mm: float, gauge_length_mm: float, knit: dict,
                        uncertainty: dict | None = None, curve: str | Path | None = None,
                        band: tuple | None = None, row_step: float = 0.005, noise_N: float | None = None,
                        end_strain: float | None = None, accuracy_rel: float = FORCE_ACCURACY_REL) -> SpecimenData:
    """Read a specimen's files and put them on the fit rows (module docstring).

    Parameters
    ----------
    name : str
    width_mm, gauge_length_mm : float
    knit : dict
        L, W0, C0 [mm].
    uncertainty : dict, optional
        Relative sd of L, W0, C0 (default 0: known).
    curve : path, optional
        A measured curve.
    band : (path, path), optional
        The lower and upper envelopes of the experimental scatter (either order).
    row_step : float
        Strain step of the rows.
    noise_N : float, optional
        sd of the curve's force [N] (a curve without a band); default: estimated from the curve.
    end_strain : float, optional
        Last strain of the rows (default: the end of the data).
    accuracy_rel : float
        Relative accuracy of the force reading: the least sd of a band's row, times the force.
    """
    if curve is None and band is None:
        raise KnitsimInputError(f"specimens.{name}: give a measured curve, an experimental band, or both")
    for key in GEOMETRY:
        if key not in knit:
            raise KnitsimInputError(f"specimens.{name}.knit.{key}: missing (the knit's {key} in mm)")
    tables = []
    cur = read_table(curve) if curve is not None else None
    lo_t = hi_t = None
    if band is not None:
        lo_t, hi_t = read_table(band[0]), read_table(band[1])
        tables += [lo_t, hi_t]
    if cur is not None:
        tables.append(cur)
    totals = {t.total for t in tables}
    if len(totals) > 1:
        raise KnitsimInputError(f"specimens.{name}: the files mix total forces and forces per wale "
                                f"({', '.join(t.source for t in tables)})")
    end = min(t.strain[-1] for t in tables)
    if end_strain is not None:
        if end_strain > end:
            raise KnitsimInputError(f"specimens.{name}.end_strain = {end_strain!r}: beyond the data (ends at {end:g})")
        end = end_strain
    n = int(np.floor(end / row_step + 1e-9))
    if n < 4:
        raise KnitsimInputError(f"specimens.{name}: the data end at strain {end:g}, fewer than 4 rows of "
                                f"{row_step:g}")
    strain = row_step * np.arange(1, n + 1)
    low = high = None
    if band is not None:
        a, b = _interp(lo_t, strain), _interp(hi_t, strain)
        low, high = np.minimum(a, b), np.maximum(a, b)
        mid = 0.5 * (low + high)
    target = _interp(cur, strain) if cur is not None else mid
    scale = max(float(np.max(np.abs(target))), 1e-300)
    if band is not None:
        half = 0.5 * (high - low)
        sigma = np.maximum(np.maximum(half, accuracy_rel * np.abs(target)), 1e-6 * scale)
        rule = f"half-width of the band, at least {100 * accuracy_rel:.3g} % of the force (the machine's accuracy)"
    else:
        if noise_N is None:
            from ..diagnosis.noise import curve_noise
            one = np.ones(len(cur.strain), int)
            nz = curve_noise(cur.strain, cur.force, one, one, source=cur.source)
            noise_N, how = float(nz.sigma_N), f"{nz.method} from the curve"
        else:
            how = "given"
        sigma = np.full(len(strain), max(float(noise_N), 1e-6 * scale))
        rule = f"noise of the curve, {noise_N:.3g} N ({how})"
    unc = {k: float((uncertainty or {}).get(k, 0.0)) for k in GEOMETRY}
    for k, v in unc.items():
        if not (0.0 <= v < 1.0):
            raise KnitsimInputError(f"specimens.{name}.uncertainty.{k} = {v!r}: expected a relative sd in [0, 1)")
    return SpecimenData(name, strain, np.asarray(target, float), sigma, low, high, totals.pop(), float(width_mm),
                        float(gauge_length_mm), {k: float(knit[k]) for k in GEOMETRY}, unc,
                        tuple(t.source for t in tables), rule)


__all__ = ["MeasuredTable", "SpecimenData", "read_table", "specimen_from_files", "GEOMETRY"]
