"""Result files: atomic writers of curves, events, summaries, resolved scenes and plots."""
from .results import (CURVE_COLUMNS, EVENT_COLUMNS, OUTPUT_FILES, atomic_write_bytes, atomic_write_text,
                      cell_summary, curve_csv, events_csv, plot_png, summarise, write_cell_results)

__all__ = ["CURVE_COLUMNS", "EVENT_COLUMNS", "OUTPUT_FILES", "atomic_write_bytes", "atomic_write_text",
           "cell_summary", "curve_csv", "events_csv", "plot_png", "summarise", "write_cell_results"]
