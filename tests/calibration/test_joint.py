"""Joint calibration (issue 16): one yarn recovered from two knits, and the scenes it writes.

Independent checks: the curves are made by the model itself with known parameters (the
truth), on two knits of one yarn, with 2 % + 0.01 N Gaussian noise and a stated W0 that
is 3 % off on each specimen; the joint fit must find the truth within 3 of its own
standard errors (and those errors small), and move each W0 from its stated value toward
the truth.  The scenes written must reproduce the fit's curve when run by the engines
(round trip: cell scene -> run_batch, patch scene -> run_patch).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from knitsim.calibration.joint import JointSetup, calibrate_joint
from knitsim.calibration.specimen import SpecimenData, read_table, specimen_from_files
from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import monotonic
from knitsim.cell.material import CellParams
from knitsim.errors import KnitsimInputError

# Dusserre's E-glass yarn with the in-plane width and m of the paper's experiment (README)
TRUTH = {"B": 0.31, "d": 0.58, "m": 0.45, "in_plane_width": 0.79}
KNITS = [{"L": 14.1, "W0": 4.4, "C0": 2.7}, {"L": 16.0, "W0": 5.0, "C0": 3.05}]
STATED_W0 = [4.4 * 1.03, 5.0 * 0.97]
WIDTH, GAUGE, STEP = 100.0, 200.0, 0.02


def _curves(seed=7):
    rng = np.random.default_rng(seed)
    out = []
    for k in KNITS:
        p = CellParams(B=TRUTH["B"], d=TRUTH["d"], m=TRUTH["m"], in_plane_width=TRUTH["in_plane_width"],
                       force_cap_N=200.0, **k)
        h = run_batch([p], monotonic(0.6, STEP))
        assert np.all(h.status == 0)
        F = h.force_per_wale[:, 0] * WIDTH / k["W0"]
        sd = 0.02 * np.abs(F) + 0.01
        out.append((h.strain, F + sd * rng.standard_normal(F.shape), sd))
    return out


def test_joint_fit_recovers_the_yarn_and_corrects_a_stated_geometry():
    specimens = [SpecimenData(f"knit{i}", s, y, sd, None, None, True, WIDTH, GAUGE,
                              {"L": k["L"], "W0": w, "C0": k["C0"]}, {"L": 0.0, "W0": 0.04, "C0": 0.0})
                 for i, ((s, y, sd), k, w) in enumerate(zip(_curves(), KNITS, STATED_W0))]
    base = CellParams(B=0.2, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.3, in_plane_width=0.7, force_cap_N=200.0)
    setup = JointSetup(base=base, shared=("B", "in_plane_width", "m"), per_specimen=("W0",), max_increment=STEP,
                       starts=8, refine=2, max_nfev=50, bounds={"B": (0.05, 2.0), "m": (0.05, 0.8)})
    r = calibrate_joint(specimens, setup)
    assert r.success and not r.flags
    for name in ("B", "in_plane_width", "m"):
        e = r.estimate(name)
        assert abs(e.value - TRUTH[name]) < 3 * e.std_error, (name, e.value, e.std_error)
        assert e.std_error < 0.05 * TRUTH[name]
    for i, k in enumerate(KNITS):
        e = r.estimate("W0", f"knit{i}")
        assert abs(e.value - k["W0"]) < 3 * e.std_error
        assert abs(e.value - k["W0"]) < 0.5 * abs(STATED_W0[i] - k["W0"])    # moved toward the truth
    # chi2 per degree of freedom near 1: the sds were the true noise
    assert 0.5 < r.s2 < 1.6
    assert r.correlation.shape == (len(r.estimates), len(r.estimates))
    # the force at grip strain 0 without a pretension: the calibrated knit's rest state (as the Warp engine's
    # run records it, row 0 of curve.csv), times the wales (a blind probe read 0 N in the report)
    from knitsim.cell.batch import run_batch
    from knitsim.cell.load_program import monotonic
    for f in r.fits:
        rest = run_batch([f.params], monotonic(0.01, 0.01)).rest["F"][0]
        assert f.pretension == 0 and f.pretension_N == pytest.approx(f.wales * rest, rel=1e-9) and rest > 0


def _write_curve(path, strain, force):
    path.write_text("strain_mm_per_mm,load_N\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(strain, force)))


def test_calibrate_command_writes_scenes_that_reproduce_its_fit(tmp_path):
    """knitsim calibrate -> materials.toml, cell and patch scenes; each scene, run, gives the fit's curve."""
    from knitsim.cli import main
    from knitsim.patch.runner import run_patch
    from knitsim.scene.cell_scene import load_cell_scene
    from knitsim.scene.patch_scene import load_patch_scene
    (s0, y0, _), (s1, y1, _) = _curves()
    _write_curve(tmp_path / "a.csv", s0, y0)
    _write_curve(tmp_path / "b.csv", s1, y1)
    scene = f"""
title = "synthetic"
[yarn]
name = "glass"
d = 0.58
B = 0.2
in_plane_width = 0.7
[friction]
m = 0.3
[rules]
force_cap_N = 200.0
[calibration]
shared = ["B", "in_plane_width", "m"]
per_specimen = []
bounds = {{ B = [0.05, 2.0], m = [0.05, 0.8] }}
max_increment = {STEP}
row_step = {STEP}
starts = 6
refine = 1
max_nfev = 40
[[specimens]]
name = "tight"
width = {WIDTH}
gauge_length = {GAUGE}
curve = "a.csv"
noise_N = 0.05
knit = {{ L = 14.1, W0 = 4.4, C0 = 2.7 }}
[[specimens]]
name = "loose"
width = {WIDTH}
gauge_length = {GAUGE}
curve = "b.csv"
noise_N = 0.05
knit = {{ L = 16.0, W0 = 5.0, C0 = 3.05 }}
"""
    (tmp_path / "cal.toml").write_text(scene)
    out = tmp_path / "out"
    status = main(["calibrate", str(tmp_path / "cal.toml"), "--out", str(out)])
    assert status == 0
    doc = json.loads((out / "calibration.json").read_text())
    assert {e["name"] for e in doc["estimates"]} == {"B", "in_plane_width", "m"}
    for sp in doc["specimens"]:
        fit = np.array(sp["curve"]["simulated_N"])
        strain = np.array(sp["curve"]["strain"])
        # the cell scene, as written: force per wale x the specimen's wales
        cs = load_cell_scene(out / f"{sp['name']}.cell.toml")
        h = run_batch(cs.params, cs.program)
        np.testing.assert_allclose(h.strain[: len(strain)], strain, rtol=1e-12)
        np.testing.assert_allclose(h.force_per_wale[: len(strain), 0] * sp["wales"], fit, rtol=1e-9)
        # the patch scene (the specimen between its grips): total force at the grip strains
        ps = load_patch_scene(out / f"{sp['name']}.patch.toml")
        hp = run_patch(ps.model, ps.program)
        np.testing.assert_allclose(hp.force_N[: len(strain)], fit, rtol=1e-9)
    lib = (out / "materials.toml").read_text()
    assert "[yarns.glass]" in lib and "[knits.tight]" in lib and "[knits.loose]" in lib
    assert (out / "fit_tight.png").stat().st_size > 1000 and "## Fits" in (out / "report.md").read_text()


def test_band_weights_and_lab_files(tmp_path):
    """The rows' sd is the band's half-width, floored at the force reading's accuracy (0.5 %)."""
    s = np.linspace(0.0, 0.2, 21)
    low, high = 10 * s, 10 * s * (1 + 0.1 * (s > 0.1))       # a band closed below 0.1, 10 % wide above
    (tmp_path / "lo.tsv").write_text("strain_mm_per_mm\tload_N\n" + "".join(f"{a}\t{b}\n" for a, b in zip(s, low)))
    (tmp_path / "hi.tsv").write_text("strain_mm_per_mm\tload_N\n" + "".join(f"{a}\t{b}\n" for a, b in zip(s, high)))
    sp = specimen_from_files("x", width_mm=50, gauge_length_mm=100, knit={"L": 4.5, "W0": 1.2, "C0": 0.9},
                             band=(tmp_path / "hi.tsv", tmp_path / "lo.tsv"), row_step=0.01)
    assert len(sp.strain) == 20 and sp.strain[-1] == pytest.approx(0.2)
    mid = 0.5 * (sp.band_low_N + sp.band_high_N)
    half = 0.5 * (sp.band_high_N - sp.band_low_N)
    np.testing.assert_allclose(sp.sigma_N, np.maximum(half, 0.005 * mid), rtol=1e-12)
    assert np.all(sp.sigma_N[sp.strain < 0.1] == 0.005 * mid[sp.strain < 0.1])     # the closed band
    assert np.all(sp.in_band(mid)) and not np.any(sp.in_band(1.2 * sp.band_high_N))
    (tmp_path / "bad.csv").write_text("strain,load_N\n0.0,0.0\n0.1,1.0\n0.05,2.0\n0.2,3.0\n")
    with pytest.raises(KnitsimInputError, match=r"bad\.csv: row 4, column strain: 0\.05 is below the rows before"):
        read_table(tmp_path / "bad.csv")
    (tmp_path / "neg.csv").write_text("strain,force_per_wale_N\n-0.02,0.0\n0.1,1.0\n0.2,2.0\n0.3,3.0\n")
    with pytest.raises(KnitsimInputError, match=r"neg\.csv: row 2, column strain: -0\.02 is negative"):
        read_table(tmp_path / "neg.csv")
    # what a lab's logger writes: an extensometer zeroed 0.001 low and a step back of 5e-5 (jitter, below
    # 1e-3 of the 0.2 strain range): read, the strain as its running maximum, the force as measured
    (tmp_path / "lab.csv").write_text("strain,force_per_wale_N\n-0.001,0.0\n0.1,1.0\n0.09995,1.01\n0.2,2.0\n")
    t = read_table(tmp_path / "lab.csv")
    np.testing.assert_array_equal(t.strain, [-0.001, 0.1, 0.1, 0.2])
    np.testing.assert_array_equal(t.force, [0.0, 1.0, 1.01, 2.0])


def test_the_calibration_refuses_the_forces_the_diagnosis_refuses(tmp_path):
    """A calibration reads its files as the diagnosis reads its curves (knitsim.diagnosis.measured):
    hand-typed files of 6 rows, force per wale rising 0, 0.1, ..., 0.5 N."""
    s = [0.0, 0.02, 0.04, 0.06, 0.08, 0.10]

    def table(name, force):
        (tmp_path / name).write_text("strain,force_per_wale_N\n" + "".join(f"{a},{b}\n" for a, b in zip(s, force)))
        return tmp_path / name
    # the column's sign reversed (a load cell mounted the other way): below zero beyond the noise. Typed to 0.1 N, its
    # noise is assumed no smaller than the rounding's sd, 0.1 / sqrt(12) = 0.0289 N: -0.1 N is 3.5 of those (within
    # 5), -0.2 N 6.9, the first row refused
    with pytest.raises(KnitsimInputError, match=r"sign\.csv: row 4, column force_per_wale_N: -0\.2 N is below zero"):
        read_table(table("sign.csv", [0.0, -0.1, -0.2, -0.3, -0.4, -0.5]))
    # a load cell not connected: zero on every row (before: a ZeroDivisionError inside the fit, and a
    # checkpoint left behind that blocked the next run)
    with pytest.raises(KnitsimInputError, match=r"zero\.csv: column force_per_wale_N: the force never rises"):
        read_table(table("zero.csv", [0.0] * 6))
    # three rows: too few
    (tmp_path / "three.csv").write_text("strain,load_N\n0,0\n0.1,1\n0.2,2\n")
    with pytest.raises(KnitsimInputError, match=r"three\.csv: 3 data row\(s\)"):
        read_table(tmp_path / "three.csv")
    # a load cell reading 2 mN below zero at rest is kept as measured
    t = read_table(table("rest.csv", [-0.002, 0.1, 0.2, 0.3, 0.4, 0.5]))
    assert t.force[0] == -0.002
    # a curve whose pre-load part was cut (first row at strain 0.06, above the first fit row 0.02): its
    # rows below 0.06 would be its first force held constant, made-up data; refused naming the file's row
    late = tmp_path / "late.csv"
    late.write_text("strain,force_per_wale_N\n" + "".join(
        f"{a + 0.06},{b}\n" for a, b in zip(s, [0.3, 0.4, 0.5, 0.6, 0.7, 0.8])))
    with pytest.raises(KnitsimInputError, match=r"late\.csv starts at strain 0\.06 \(row 2\), above the first row"):
        specimen_from_files("x", width_mm=50, gauge_length_mm=100, knit={"L": 4.5, "W0": 1.2, "C0": 0.9},
                            curve=late, row_step=0.02)


def test_one_test_given_to_two_specimens_is_refused_before_any_work(tmp_path):
    """A lab's copy of one test, re-exported from Excel (BOM, ';', decimal commas, CRLF, a unit in the header),
    given as a second specimen: its rows would count twice.  Before, it was fitted without a word (a blind probe:
    B 0.31198 +- 0.00214 against 0.31207 +- 0.00306 from the one file, the sd / sqrt(2)); refused now, naming both
    specimens and files, before any solve.  Two different tests of one knit are read."""
    from knitsim.cli import main
    s = [0.0, 0.02, 0.04, 0.06, 0.08, 0.10]
    f = [0.0, 0.11, 0.19, 0.32, 0.41, 0.48]
    (tmp_path / "a.csv").write_text("strain,force_per_wale_N\n" + "".join(f"{x},{y}\n" for x, y in zip(s, f)))
    (tmp_path / "a_excel.csv").write_bytes(("\ufeffStrain [-];force_per_wale_N\r\n" + "".join(
        f"{x};{y}\r\n".replace(".", ",") for x, y in zip(s, f))).encode("utf-8"))
    (tmp_path / "b.csv").write_text("strain,force_per_wale_N\n" + "".join(
        f"{x},{y + 0.01}\n" for x, y in zip(s, f)))
    knit = {"L": 14.1, "W0": 4.4, "C0": 2.7}
    base = CellParams(B=0.31, d=0.58, m=0.45, in_plane_width=0.79, force_cap_N=200.0, **knit)
    setup = JointSetup(base=base, shared=("B",), per_specimen=(), max_increment=0.02, starts=1, refine=1, max_nfev=2)

    def specimens(second):
        return [specimen_from_files(n, width_mm=100, gauge_length_mm=200, knit=knit, curve=tmp_path / c,
                                    row_step=0.02) for n, c in (("first", "a.csv"), ("second", second))]
    from knitsim.calibration.joint import check_setup
    for copy in ("a.csv", "a_excel.csv"):
        with pytest.raises(KnitsimInputError, match=rf"specimens\[1\]\.curve: .*{copy.replace('.', r'[.]')} holds the "
                                                     r"same rows as specimens\[0\]\.curve \(.*a\.csv\)"):
            check_setup(specimens(copy), setup)
    check_setup(specimens("b.csv"), setup)                  # another test: read
    # the command: refused with exit status 2, nothing written
    scene = tmp_path / "cal.toml"
    scene.write_text("""[yarn]\nd = 0.58\nB = 0.31\n[friction]\nm = 0.45\n[calibration]\nshared = ["B"]\nper_specimen = []
max_increment = 0.02\nrow_step = 0.02\n""" + "".join(f"""[[specimens]]\nname = "{n}"\nwidth = 100.0\ngauge_length = 200.0
curve = "{c}"\nknit = {{ L = 14.1, W0 = 4.4, C0 = 2.7 }}\n""" for n, c in (("first", "a.csv"), ("second", "a_excel.csv"))))
    assert main(["calibrate", str(scene), "--out", str(tmp_path / "out")]) == 2
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("objective", ["midline", "band"])
def test_an_interrupted_calibration_resumes_to_the_same_fit_without_redoing_work(tmp_path, monkeypatch, objective):
    """Stopped twice (during the screening's aftermath and inside a refinement: under the band objective,
    inside its second stage), resumed from its checkpoint: the same estimates bit for bit (least squares
    replays the saved evaluations), and the evaluations done in all three runs are those of one
    uninterrupted fit (none redone)."""
    from knitsim.calibration import joint
    specimens = [SpecimenData(f"knit{i}", s, y, sd, None, None, True, WIDTH, GAUGE,
                              {"L": k["L"], "W0": w, "C0": k["C0"]}, {"L": 0.0, "W0": 0.04, "C0": 0.0})
                 for i, ((s, y, sd), k, w) in enumerate(zip(_curves(), KNITS, STATED_W0))]
    base = CellParams(B=0.2, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.3, in_plane_width=0.7, force_cap_N=200.0)
    setup = JointSetup(base=base, shared=("B", "m"), per_specimen=("W0",), max_increment=STEP,
                       starts=3, refine=2, max_nfev=8, bounds={"B": (0.05, 2.0), "m": (0.05, 0.8)},
                       objective=objective)
    calls = []
    real = joint._Problem.evaluate_with_jacobian
    monkeypatch.setattr(joint._Problem, "evaluate_with_jacobian",
                        lambda self, x, **kw: calls.append(1) or real(self, x, **kw))
    full = calibrate_joint(specimens, setup)
    n_full = len(calls)
    calls.clear()
    ck = tmp_path / "ck.pkl"
    with pytest.raises(joint.CalibrationInterrupted):
        calibrate_joint(specimens, setup, checkpoint=ck, stop_after=3)
    with pytest.raises(joint.CalibrationInterrupted):
        calibrate_joint(specimens, setup, checkpoint=ck, resume=True, stop_after=n_full - 6)
    ticks = []
    again = calibrate_joint(specimens, setup, checkpoint=ck, resume=True,
                            counter=lambda what, total: (lambda done: ticks.append((what, done, total))))
    assert n_full > 9 and len(calls) == n_full
    assert [e.value for e in again.estimates] == [e.value for e in full.estimates]
    assert [e.std_error for e in again.estimates] == [e.std_error for e in full.estimates]
    assert again.starts == full.starts and again.chi2 == full.chi2
    assert ticks[0] == ("starts screened", 4, 4)            # resumed: the screening was done
    # another setup does not take this checkpoint
    with pytest.raises(KnitsimInputError, match="belongs to other specimens or another calibration setup"):
        calibrate_joint(specimens, JointSetup(base=base, shared=("B",), per_specimen=("W0",), max_increment=STEP),
                        checkpoint=ck, resume=True)


def test_pretension_of_a_model_curve_is_recovered():
    """A curve made by the model with a known pretension (the knit at strain 0.04 at grip strain 0,
    the rows at knit strain (1.04)(1 + e) - 1, an exact program of the cell) is fitted with the
    pretension free (and B): both come back within 3 standard errors, the force at grip strain 0 is the
    cell's at strain 0.04, and the patch scene written from it reproduces the curve."""
    from knitsim.calibration.specimen import pretension_strain
    from knitsim.cell.load_program import piecewise_linear
    from knitsim.patch.model import PatchModel
    from knitsim.patch.runner import run_patch
    k, pre, step = KNITS[0], 0.04, 0.02
    truth = CellParams(B=TRUTH["B"], d=TRUTH["d"], m=TRUTH["m"], in_plane_width=TRUTH["in_plane_width"],
                       force_cap_N=200.0, **k)
    grip = step * np.arange(1, 26)
    knit_strain = pretension_strain(grip, pre)
    assert np.allclose(knit_strain, pre + grip * (1 + pre))                      # the identity
    h = run_batch([truth], piecewise_linear([0.0, pre] + list(knit_strain), 0.005))
    F_all = h.force_per_wale[:, 0] * WIDTH / k["W0"]
    at = np.searchsorted(h.strain, knit_strain - 1e-12)
    assert np.allclose(h.strain[at], knit_strain)
    F = F_all[at]
    F_pre = F_all[np.searchsorted(h.strain, pre - 1e-12)]
    sd = 0.005 * F + 0.01
    sp = SpecimenData("pre", grip, F, sd, None, None, True, WIDTH, GAUGE, dict(k), {}, pretension=0.0,
                      pretension_sd=0.05)
    base = CellParams(B=0.2, d=TRUTH["d"], m=TRUTH["m"], in_plane_width=TRUTH["in_plane_width"], force_cap_N=200.0,
                      **k)
    setup = JointSetup(base=base, shared=("B",), per_specimen=("pretension",), max_increment=0.005, starts=6,
                       refine=2, max_nfev=40, bounds={"B": (0.05, 2.0), "pretension": (0.0, 0.1)})
    r = calibrate_joint([sp], setup)
    assert r.success
    for name, spec, true in (("B", None, TRUTH["B"]), ("pretension", "pre", pre)):
        e = r.estimate(name, spec)
        assert abs(e.value - true) < 3 * e.std_error + 1e-4, (name, e.value, e.std_error)
    fit = r.fits[0]
    assert fit.pretension == pytest.approx(pre, abs=2e-3)
    assert fit.pretension_N == pytest.approx(F_pre, rel=0.03)
    # the specimen between its grips, pretensioned: the patch at grip strain e is the cell at (1 + p)(1 + e) - 1
    model = PatchModel.specimen(truth, WIDTH, GAUGE, pretension=pre)
    from knitsim.cell.load_program import pretensioned
    ph = run_patch(model, pretensioned(monotonic(grip[-1], step), model.grip_offset, 0.005))
    rows = np.searchsorted(ph.grip_strain, grip - 1e-9)
    assert np.allclose(ph.grip_strain[rows], grip, atol=1e-12)
    assert np.allclose(ph.force_N[rows], F, rtol=1e-6, atol=1e-9)
    assert ph.grip_strain[0] < 0                                   # pretensioning, before the strain origin
    # the written specimen (fitted cell and pretension) reproduces the fit's curve, which reads the rows
    # as its patch scene runs it (the fit read its rows between increments; the report runs the specimen)
    fm = PatchModel.specimen(fit.params, WIDTH, GAUGE, pretension=fit.pretension)
    fh = run_patch(fm, pretensioned(monotonic(grip[-1], step), fm.grip_offset, 0.005))
    rows = np.searchsorted(fh.grip_strain, grip - 1e-9)
    np.testing.assert_allclose(fh.force_N[rows], fit.simulated_N, rtol=1e-9)


def test_m_held_above_the_truth_by_the_scenes_bound_is_said_at_the_stated_end():
    """Model curves of m = 0.45 fitted with m bounded to [0.6, 0.8]: m ends at 0.6, the low end the scene stated,
    which the flag must say (before: "no friction at the crossing", the meaning of m = 0)."""
    specimens = [SpecimenData(f"knit{i}", s, y, sd, None, None, True, WIDTH, GAUGE, dict(k))
                 for i, ((s, y, sd), k) in enumerate(zip(_curves(), KNITS))]
    base = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.7, in_plane_width=0.79, force_cap_N=200.0)
    setup = JointSetup(base=base, shared=("B", "m"), per_specimen=(), max_increment=STEP, starts=2, refine=1,
                       max_nfev=20, bounds={"B": (0.05, 2.0), "m": (0.6, 0.8)})
    r = calibrate_joint(specimens, setup)
    e = r.estimate("m")
    assert e.at_bound == "low" and e.value == pytest.approx(0.6), (e.value, e.at_bound)
    flag = next(f for f in r.flags if f.startswith("m = "))
    assert "the low end of the stated range" in flag and "no friction" not in flag, flag
