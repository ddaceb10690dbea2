"""What the commands share: a user error with its exit status, settings from the environment, checks
of paths and ports given on the command line (a message in words, never a traceback)."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from pydantic import ValidationError

from tryon.config import Settings

# Exit status of a usage error (argparse's own).
EXIT_USAGE = 2


class CliError(Exception):
    """A mistake the user can fix: ``main`` prints ``tryon <command>: <message>`` and exits with ``code``."""

    def __init__(self, message: str, code: int = EXIT_USAGE):
        super().__init__(message)
        self.code = code


def load_settings() -> Settings:
    """``Settings()`` from the environment; a bad ``TRYON_*`` value is a ``CliError`` naming the variable."""
    try:
        return Settings()
    except ValidationError as exc:
        problems = []
        for e in exc.errors():
            name = "TRYON_" + "_".join(str(x) for x in e.get("loc", ())).upper()
            problems.append(f"{name}={e.get('input')!r}: {e.get('msg', 'invalid')}")
        raise CliError("bad setting in the environment: " + "; ".join(problems)) from None


def writable_dir(path: Path, what: str) -> Path:
    """Create ``path`` (and parents) and check that a file can be written in it; ``CliError`` if not."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise CliError(f"cannot write to {what} {path}: {exc.strerror or exc}") from None
    return path


def port_number(text: str) -> int:
    """argparse type: a TCP port, 0-65535 (0: any free port). Larger numbers are refused (the socket
    layer would otherwise bind the number modulo 65536)."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"a TCP port is 0-65535, got {port}")
    return port
