"""Scene files: a declarative schema layer (:mod:`.schema`) and cell scenes (:mod:`.cell_scene`).

A scene is a TOML file describing what to simulate (materials, geometry,
friction, rules, load program, outputs, device).  Scenes are validated in full,
with messages naming the key path and the value, before any work starts.
"""
from .cell_scene import CELL_SCENE, CellScene, load_cell_scene
from .schema import OPTIONAL, REQUIRED, Field, Table, TableArray, dumps, set_value, validate

__all__ = ["CELL_SCENE", "CellScene", "load_cell_scene", "Field", "Table", "TableArray", "REQUIRED",
           "OPTIONAL", "validate", "set_value", "dumps"]
