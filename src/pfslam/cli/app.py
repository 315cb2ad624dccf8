"""The ``pfslam`` program: the Typer app with its help panels, the consoles, exit codes and
signals, and :func:`main`."""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import sys
from typing import Any, Callable, Optional, TypeVar

import typer
from rich.console import Console
from rich.markup import escape
from typer.core import TyperCommand, TyperGroup, TyperOption

from pfslam.errors import PfslamError

# -- help: panels, each default stated once, value names instead of type tags ----------------

# The panels options are grouped in, in the order they appear in a command's signature.
INPUT = "Input"
OUTPUT = "Output"
FILTER = "Filter"
ODOMETRY = "Odometry"
VIEWS = "Views"
BAGS = "ROS bags"


def _help_option(option: Any, params: list[Any]) -> Any:
    """The --help option without a type tag, listed last in the Output panel (else the last
    panel of ``params``)."""
    if option is not None:
        option.metavar = ""
        named = [p.rich_help_panel for p in params if isinstance(p, TyperOption) and p.rich_help_panel]
        if named:
            option.rich_help_panel = OUTPUT if OUTPUT in named else named[-1]
    return option


class _Command(TyperCommand):
    """A command whose --help is listed last in the Output panel, without a type tag (each
    option's default is stated in its own help: see :func:`pfslam.cli.options.opt`)."""

    def get_help_option(self, ctx: Any) -> Any:
        return _help_option(super().get_help_option(ctx), self.params)


class _Group(TyperGroup):
    """The ``pfslam`` group: its --help without a type tag."""

    def get_help_option(self, ctx: Any) -> Any:
        return _help_option(super().get_help_option(ctx), self.params)


app = typer.Typer(
    cls=_Group,
    add_completion=False,
    no_args_is_help=True,
    help="Particle-filter SLAM and Monte Carlo localization for 2D lidar logs.",
    pretty_exceptions_enable=False,
)


class StdoutError(Exception):
    """Standard output could not be written (a full disk, a closed pipe); main() reports it."""

    def __init__(self, error: OSError) -> None:
        super().__init__(str(error))
        self.error = error


class Stdout:
    """What ``out_console`` writes to: ``sys.stdout`` at the moment of writing (tests swap it),
    a failed write raised as :class:`StdoutError` so that no handler takes it for a file's error."""

    def write(self, text: str) -> int:
        try:
            return sys.stdout.write(text)
        except OSError as e:
            raise StdoutError(e) from None

    def flush(self) -> None:
        try:
            sys.stdout.flush()
        except OSError as e:
            raise StdoutError(e) from None

    def __getattr__(self, name: str) -> Any:
        return getattr(sys.stdout, name)


out_console = Console(file=Stdout())  # type: ignore[arg-type]
err_console = Console(stderr=True)

F = TypeVar("F", bound=Callable[..., Any])

# A usage error (unknown option, missing argument, a value of the wrong type): Typer's public
# BadParameter derives from it (Typer carries its own Click and does not export the class).
UsageError: Any = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")


def error(text: str) -> None:
    """One line on stderr; ``text`` is printed as is (file names may hold [brackets])."""
    err_console.print(f"[bold red]error:[/] {escape(text)}", highlight=False, soft_wrap=True)


def warn(text: str) -> None:
    err_console.print(f"[yellow]warning:[/] {escape(text)}", highlight=False, soft_wrap=True)


# Stop signals this process received (SIGTERM, and SIGINT while results were being written):
# main() reports a run stopped by SIGTERM with exit code 143 instead of Ctrl-C's 130.
_received: list[int] = []


def received_signals() -> list[int]:
    """The stop signals received during this process's commands (SIGTERM makes the exit code 143)."""
    return _received


EXIT_INTERRUPTED = 130  # 128 + SIGINT
EXIT_TERMINATED = 143  # 128 + SIGTERM
EXIT_CLOSED_PIPE = 141  # 128 + SIGPIPE: the reader of stdout went away (e.g. `| head`)


def _terminate(sig: int, frame: Any) -> None:
    """SIGTERM (batch schedulers, `timeout`) stops a run like Ctrl-C: the loops that keep what
    they computed on KeyboardInterrupt keep it, the results are written, then the exit is 143."""
    _received.append(sig)
    raise KeyboardInterrupt


def guarded(fn: F) -> F:
    """Turn pfslam's own errors into one line on stderr and exit code 2 (a standard output that
    fails, :class:`StdoutError`, passes through to main(), which reports it for every command)."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except PfslamError as e:
            error(str(e))
            raise typer.Exit(2) from None
        except OSError as e:  # e.g. an output folder that cannot be written
            where = e.filename if e.filename is not None else "pfslam"
            error(f"{where}: {e.strerror or e}")
            raise typer.Exit(2) from None
        except MemoryError:
            error("out of memory: fewer particles, a coarser map or a shorter log would fit")
            raise typer.Exit(2) from None
        except KeyboardInterrupt:
            err_console.print("[yellow]interrupted[/]", highlight=False)
            raise typer.Exit(EXIT_INTERRUPTED) from None

    return wrapper  # type: ignore[return-value]


def command(name: Optional[str] = None, **context: Any) -> Callable[[F], F]:
    """``@app.command`` with :class:`_Command`'s help; ``context``: Click context settings."""
    return app.command(name, cls=_Command, context_settings=context or None)


def _stdout_failed(e: OSError) -> int:
    """Report a standard output that cannot be written; the exit code. A closed pipe is
    quiet (the reader has all it wanted: 141), anything else one line on stderr and 2."""
    try:  # what is still buffered goes nowhere, so the interpreter's last flush cannot fail again
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass
    if isinstance(e, BrokenPipeError):
        return EXIT_CLOSED_PIPE
    error(f"standard output: {e.strerror or e}")
    return 2


def main() -> None:
    """The ``pfslam`` program: like ``app()``, but a usage error (unknown option, missing
    argument, a value of the wrong type) is one line on stderr rather than a framed box;
    SIGTERM stops a run like Ctrl-C (results kept) with exit code 143; a standard output
    that cannot be written is one line and exit code 2 (a closed pipe: a quiet exit, 141)."""
    with contextlib.suppress(ValueError):  # ValueError: not the main thread (embedded): no handler
        signal.signal(signal.SIGTERM, _terminate)
    try:
        code = app(standalone_mode=False)
        sys.stdout.flush()
    except UsageError as e:
        where = e.ctx.command_path if e.ctx is not None else "pfslam"
        if e.format_message().strip():  # empty: no arguments at all, and the help was shown
            error(f"{where}: {e.format_message()} (see '{where} --help')")
        code = 2
    except typer.Abort:  # Ctrl-C outside a command's own handling
        err_console.print("[yellow]interrupted[/]", highlight=False)
        code = EXIT_INTERRUPTED
    except StdoutError as e:
        code = _stdout_failed(e.error)
    except OSError as e:  # outside the commands only Typer's own text (help) is written: to stdout
        if e.filename is not None:
            raise
        code = _stdout_failed(e)
    code = code if isinstance(code, int) else 0
    if code == EXIT_INTERRUPTED and signal.SIGTERM in _received:
        code = EXIT_TERMINATED
    sys.exit(code)
