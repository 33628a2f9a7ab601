"""Exception types and the CLI exit codes they map to.

User errors subclass builtins (ConfigError is a ValueError) so library users can catch them
naturally; the CLI prints `str(exc)` as one line and exits with the class's `exit_code`.
"""


class IpsphError(Exception):
    """Base of every error ipsph raises on purpose."""

    exit_code = 1


class InputError(IpsphError, ValueError):
    """Bad input of any kind: reported before any large allocation or output (exit 2)."""

    exit_code = 2


class ConfigError(InputError):
    """A scene file or setting is malformed, unknown, mistyped or out of range."""


class MeshError(InputError):
    """A mesh cannot be read or is unusable (empty, open, zero volume, ...)."""


class OutputError(InputError):
    """The output folder is unusable (not writable, holds an earlier run, ...)."""


class NumericalFailure(IpsphError, RuntimeError):
    """The simulation diverged (NaN/Inf, escaped particles): exit 3, finished frames kept."""

    exit_code = 3


class WriteError(IpsphError, OSError):
    """Writing a frame failed (disk full, ...): earlier frames stay intact."""

    exit_code = 4


EXIT_OK = 0
EXIT_INPUT = 2
EXIT_NUMERICAL = 3
EXIT_INTERRUPTED = 130


def read_text(path, where: str, what: str = "scene file") -> str:
    """A text file's contents, or a one-line ConfigError naming it as given and as resolved."""
    from pathlib import Path

    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(
            f"{where}: cannot read {what} (resolved: {Path(path).resolve()}): {' '.join(str(exc).split())}"
        ) from exc
