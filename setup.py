"""Package discovery only; all metadata is in pyproject.toml.

``kernels/`` (Warp device code) sits at the top of the repository, as the
project layout asks, and ships inside the distribution as ``knitsim.kernels``.
"""
from setuptools import find_packages, setup

packages = find_packages(include=["knitsim", "knitsim.*"])
packages += ["knitsim." + p for p in find_packages(include=["kernels", "kernels.*"])]

setup(packages=packages, package_dir={"knitsim.kernels": "kernels"})
