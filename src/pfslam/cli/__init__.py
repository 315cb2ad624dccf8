"""The ``pfslam`` command line. All printing and exit codes live here.

Modules: :mod:`~pfslam.cli.app` (the app, consoles, exit codes, :func:`main`),
:mod:`~pfslam.cli.options` (shared options, settings from options), :mod:`~pfslam.cli.render`
(progress, tables, a run's report), :mod:`~pfslam.cli.run_commands` (slam, calibrate,
localize, convert), :mod:`~pfslam.cli.tool_commands` (simulate, demo, evaluate, sweep,
dump-config, version).
"""

from pfslam.cli import run_commands, tool_commands  # noqa: F401 (the commands register on the app)
from pfslam.cli.app import EXIT_CLOSED_PIPE, EXIT_INTERRUPTED, EXIT_TERMINATED, app, main

__all__ = ["EXIT_CLOSED_PIPE", "EXIT_INTERRUPTED", "EXIT_TERMINATED", "app", "main"]
