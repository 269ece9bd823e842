"""Sim-to-real gap diagnosis: measured curves, gap per stage, baseline calibration (issue 6 groundwork)."""
