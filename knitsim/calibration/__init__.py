"""Joint calibration of one yarn on several specimens, and its calibrated materials (issue 16).

- :mod:`knitsim.calibration.specimen`: a specimen's measured data (curves, experimental
  bands) on the rows of the fit, with the weights of each row;
- :mod:`knitsim.calibration.joint`: the joint least squares (shared yarn, per-specimen knit),
  with uncertainties, correlations, bound flags and the one-yarn check;
- :mod:`knitsim.calibration.scene`: the calibration scene (TOML) that ``knitsim calibrate`` reads;
- :mod:`knitsim.calibration.outputs`: what it writes (material library, cell and patch scenes,
  JSON, report, plots).
"""
from .joint import Estimate, JointResult, JointSetup, OneYarnCheck, SpecimenFit, calibrate_joint
from .specimen import SpecimenData, read_table, specimen_from_files

__all__ = ["Estimate", "JointResult", "JointSetup", "OneYarnCheck", "SpecimenFit", "calibrate_joint", "SpecimenData", "read_table",
           "specimen_from_files"]
