"""What every command needs besides the control: batches of runs, complete files, tables and JSON, install hints.

* :mod:`~isf_robot.support.parallel`: a batch of independent tasks, here, in worker processes or on
  Ray, stopped cleanly by Ctrl-C (``compare``, ``sweep``, the satellite study).
* :mod:`~isf_robot.support.files`: files that appear complete under their name or not at all.
* :mod:`~isf_robot.support.report`: JSON cleaning, the schema tag of every JSON document, plain-text
  tables.
* :mod:`~isf_robot.support.extras`: how a message names an optional extra.
* :mod:`~isf_robot.support.messages`: the commands' warnings as one line each, workers included.
* :mod:`~isf_robot.support.progress`: a long run's progress on a terminal, one line rewritten in place.

Imported by the arm, the satellite, the recorders, the plots and the command lines; it imports from
the project only the core's exceptions (:mod:`isf_robot.core.exceptions`), and the core imports nothing
from here. Public names load on first use: the project's one export style (:mod:`isf_robot._exports`).
"""

from __future__ import annotations

from isf_robot._exports import lazy_exports

_EXPORTS: dict[str, str] = {
    "run_tasks": "parallel", "Interrupted": "parallel", "Terminated": "parallel", "MAX_JOBS": "parallel",
    "check_backend": "parallel", "BACKENDS": "parallel",
    "write_text_atomic": "files", "write_bytes_atomic": "files", "partial_path": "files",
    "check_output_path": "files", "commit_partial": "files", "PARTIAL_SUFFIX": "files",
    "to_jsonable": "report", "format_table": "report", "format_value": "report", "mean_std_cell": "report",
    "with_schema": "report", "schema_id": "report", "SCHEMAS": "report",
    "EXTRAS": "extras", "install_hint": "extras",
    "one_line_warnings": "messages", "WARN_ENV": "messages",
    "TerminalProgress": "progress",
}

__all__, __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
