"""Exceptions raised by pfslam. The CLI turns them into one-line messages."""


class PfslamError(Exception):
    """Base class of every error pfslam raises on purpose."""


class InputError(PfslamError):
    """A log, map or config file is missing, corrupt, or inconsistent."""

    def __init__(self, path: object, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class ConfigError(PfslamError):
    """A configuration value is invalid."""
