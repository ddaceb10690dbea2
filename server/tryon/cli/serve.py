"""``tryon serve``: run the service with uvicorn."""

from __future__ import annotations

import argparse
import sqlite3

from tryon.cli.common import CliError, load_settings, port_number, writable_dir


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("serve", help="run the HTTP/WebSocket service")
    p.add_argument("--host", default="127.0.0.1", help="interface to bind (default 127.0.0.1)")
    p.add_argument("--port", type=port_number, default=8000, help="TCP port, 0-65535 (default 8000)")
    p.add_argument("--log-level", default="info", choices=["critical", "error", "warning", "info", "debug"])
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import uvicorn

    from tryon.api.app import create_app
    from tryon.garment.catalogue import Catalogue

    settings = load_settings()
    writable_dir(settings.data_dir, "the data directory (TRYON_DATA_DIR)")
    try:  # a broken index would otherwise be a 500 on every catalogue request
        Catalogue(settings.data_dir)
    except (OSError, sqlite3.Error) as exc:
        reason = getattr(exc, "strerror", None) or exc  # the system's words (sqlite's for a broken index)
        raise CliError(f"cannot open the catalogue in {settings.data_dir}: {reason}") from None
    if not (settings.web_dir / "index.html").is_file():
        raise CliError(f"the page's files are missing: no index.html in {settings.web_dir}")
    uvicorn.run(create_app(settings), host=args.host, port=args.port, log_level=args.log_level)
    return 0
