"""Numbers reported by the source papers, bundled with the package.

``dusserre2015.toml``: every number of Dusserre (2015), Eur. J. Mech. A/Solids 51,
160-171 (yarns, knit, capstan Table 2, friction law Table 3, apparent friction,
claims).  ``dahl_kes.toml``: Dahl parameters of the Gemtex KES bending paper.
"""
from __future__ import annotations

import tomllib
from functools import lru_cache
from importlib import resources
from typing import Any


@lru_cache(maxsize=None)
def load(name: str) -> dict[str, Any]:
    """Load a bundled data file by stem, e.g. ``load("dusserre2015")``."""
    text = resources.files(__name__).joinpath(f"{name}.toml").read_text(encoding="utf-8")
    return tomllib.loads(text)


def dusserre2015() -> dict[str, Any]:
    """The Dusserre (2015) transcription (see the module docstring)."""
    return load("dusserre2015")


def dahl_kes() -> dict[str, Any]:
    """The Dahl parameters identified from KES bending loops (Gemtex)."""
    return load("dahl_kes")
