"""Exception types and the CLI exit codes they map to.

User errors subclass builtins (ConfigError is a ValueError) so library users can catch them
naturally; the CLI prints `str(exc)` as one line and exits with the class's `exit_code`.
The exit codes are declared once, here.
"""

EXIT_OK = 0
EXIT_ERROR = 1  # an error with no code of its own (also: some members of a sweep failed)
EXIT_INPUT = 2  # bad input, refused before any large allocation or output
EXIT_NUMERICAL = 3  # the simulation diverged; finished frames kept
EXIT_WRITE = 4  # a write failed (disk full); earlier frames intact
EXIT_INTERRUPTED = 130  # SIGINT / SIGTERM: a final frame and a checkpoint were written


class IpsphError(Exception):
    """Base of every error ipsph raises on purpose."""

    exit_code = EXIT_ERROR


class InputError(IpsphError, ValueError):
    """Bad input of any kind: reported before any large allocation or output (exit 2)."""

    exit_code = EXIT_INPUT


class ConfigError(InputError):
    """A scene file or setting is malformed, unknown, mistyped or out of range."""


class MeshError(InputError):
    """A mesh cannot be read or is unusable (empty, open, zero volume, ...)."""


class OutputError(InputError):
    """The output folder is unusable (not writable, holds an earlier run, ...)."""


class NumericalFailure(IpsphError, RuntimeError):
    """The simulation diverged (NaN/Inf, escaped particles): exit 3, finished frames kept."""

    exit_code = EXIT_NUMERICAL


class WriteError(IpsphError, OSError):
    """Writing a frame failed (disk full, ...): earlier frames stay intact."""

    exit_code = EXIT_WRITE


def read_text(path, where: str, what: str = "scene file") -> str:
    """A text file's contents, or a one-line ConfigError naming it as given and as resolved."""
    from pathlib import Path

    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(
            f"{where}: cannot read {what} (resolved: {Path(path).resolve()}): {' '.join(str(exc).split())}"
        ) from exc
