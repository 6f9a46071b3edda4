"""The experiment framework of the benchmark: cells (one study x task x airframe x controller x seed x
draw each), a cache of finished cells, statistics over the replicates, local and Ray runners, and the
tables and ``results.json`` of a sweep.

    cells = [Cell("altitude", "altitude", airframe, controller, seed) for ...]
    results = run_cells(cells, CellCache("runs/experiment/cells"), runner="local", workers=4)
    groups = group_cells(cells, results)
    print(markdown_table(rows_from_groups(groups), [Column("rmse_m", "RMSE (m)")]))

A study registers its cell function in :data:`CELL_FUNCTIONS` ("module:attribute").
The public names load on first use (PEP 562).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .cache import CellCache
    from .cells import CELL_FUNCTIONS, Cell, code_version, register_cell_function, run_cell
    from .results import (
        Column,
        Row,
        experiment_document,
        latex_table,
        markdown_table,
        rows_from_groups,
        write_results,
    )
    from .runners import CellsFailedError, run_cells
    from .statistics import Aggregate, CellGroup, aggregate, group_cells

__all__ = ["CELL_FUNCTIONS", "Aggregate", "Cell", "CellCache", "CellGroup", "CellsFailedError", "Column",
           "Row", "aggregate", "code_version", "experiment_document", "group_cells", "latex_table",
           "markdown_table", "register_cell_function", "rows_from_groups", "run_cell", "run_cells",
           "write_results"]
#: Public name -> the submodule that defines it.
_LAZY = {"CellCache": "cache", "CELL_FUNCTIONS": "cells", "Cell": "cells", "code_version": "cells",
         "register_cell_function": "cells", "run_cell": "cells", "CellsFailedError": "runners",
         "run_cells": "runners", "Aggregate": "statistics", "CellGroup": "statistics",
         "aggregate": "statistics", "group_cells": "statistics", "Column": "results", "Row": "results",
         "experiment_document": "results", "latex_table": "results", "markdown_table": "results",
         "rows_from_groups": "results", "write_results": "results"}


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, __all__)
