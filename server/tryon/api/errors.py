"""Error answers in words: request validation (422) and unreadable bodies (400), always valid JSON.

FastAPI's default 422 handler echoes each bad input back; a NaN or an infinity in the request (Python's
``json`` reads ``NaN``, ``Infinity`` and ``1e400``) then cannot be written as JSON and the client gets a
500 instead of the 422. These handlers write such numbers as strings, cut long echoed inputs short, and
say in words what is wrong with a body that is not JSON. An ``/api/`` request that no route takes (the
page's static files, mounted at ``/``, would answer a bare 404, or a 405 allowing GET) gets a 405 with the
methods the path does take, or a 404 naming the path.
"""

from __future__ import annotations

import logging
import math
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.routing import Match, Mount
from starlette.exceptions import HTTPException as StarletteHTTPException

# characters of a bad input echoed back in a 422 (a 60 MB string field is not sent back whole)
ECHO_MAX_CHARS = 200
# items of an echoed list, and levels of nesting, past which the echo is cut (same reason)
ECHO_MAX_ITEMS = 50
ECHO_MAX_DEPTH = 12
# FastAPI's own words for a body it could not read (not JSON-decodable for another reason than syntax)
_FASTAPI_PARSE_ERROR = "There was an error parsing the body"

log = logging.getLogger(__name__)


def json_safe(value: Any, depth: int = 0) -> Any:
    """``value`` with non-finite floats as the strings ``"NaN"``, ``"Infinity"``, ``"-Infinity"``, long
    strings and bytes cut to ``ECHO_MAX_CHARS``, lists to ``ECHO_MAX_ITEMS``, anything nested deeper than
    ``ECHO_MAX_DEPTH`` as ``"..."`` (a 500-deep list would exhaust the stack), exceptions as their message."""
    if depth > ECHO_MAX_DEPTH:
        return "..."
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("Infinity" if value > 0 else "-Infinity")
    if isinstance(value, (bytes, bytearray)):
        value = value.decode("utf-8", errors="replace")
    if isinstance(value, str):
        return value if len(value) <= ECHO_MAX_CHARS else value[:ECHO_MAX_CHARS] + f"... ({len(value):,} characters)"
    if isinstance(value, dict):
        return {str(k): json_safe(v, depth + 1) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        items = [json_safe(v, depth + 1) for v in value[:ECHO_MAX_ITEMS]]
        return items + ([f"... ({len(value):,} items)"] if len(value) > ECHO_MAX_ITEMS else [])
    if isinstance(value, BaseException):
        return str(value)
    if value is None or isinstance(value, (bool, int, float)):
        return value
    return json_safe(str(value), depth)


def _is_json(content_type: str | None) -> bool:
    main = (content_type or "").split(";")[0].strip().lower()
    return main == "application/json" or (main.startswith("application/") and main.endswith("+json"))


def _reworded(error: dict, request: Request) -> dict:
    """FastAPI's two errors about the body as a whole, and its error for a text field where a file was
    expected, in words a client can act on."""
    loc = tuple(error.get("loc", ()))
    if error.get("type") == "json_invalid":
        where = f" at offset {loc[1]}" if len(loc) > 1 else ""
        reason = (error.get("ctx") or {}).get("error", "")
        return {**error, "msg": f"the body is not valid JSON{where}" + (f": {reason}" if reason else "")}
    if error.get("type") == "value_error" and "Expected UploadFile" in str(error.get("msg")):
        # FastAPI's "Expected UploadFile, received: <class 'str'>" names a Python class
        plain = {k: v for k, v in error.items() if k != "ctx"}
        return {**plain, "msg": "expected a file (a form part with a file name), got a text field"}
    content_type = request.headers.get("content-type")
    if loc == ("body",) and error.get("type") == "model_attributes_type" and not _is_json(content_type):
        return {**error, "msg": "the body must be a JSON object sent with Content-Type: application/json "
                                f"(got Content-Type: {content_type or 'none'})"}
    return error


async def validation_error(request: Request, exc: RequestValidationError) -> JSONResponse:
    """422 naming every bad field; the echoed inputs made JSON-safe."""
    errors = [_reworded(e, request) for e in exc.errors()]
    return JSONResponse(status_code=422, content={"detail": json_safe(errors)})


async def http_error(request: Request, exc: StarletteHTTPException):
    """FastAPI's "There was an error parsing the body" (400) with the reason in our words
    (``_unreadable_body``), unrouted ``/api/`` requests in words (``_no_api_route``); everything else as
    usual."""
    if exc.status_code == 400 and exc.detail == _FASTAPI_PARSE_ERROR:
        reason = _unreadable_body(exc.__cause__)
        return JSONResponse({"detail": f"could not read the request body as JSON: {reason}"}, status_code=400)
    if exc.status_code in (404, 405) and request.url.path.startswith("/api/") and _unrouted(request):
        return _no_api_route(request)
    return await http_exception_handler(request, exc)


def _unreadable_body(cause: BaseException | None) -> str:
    """Why a body could not be read, in our words; the exception itself (a library's or Python's text,
    such as "use sys.set_int_max_str_digits() to increase the limit") is logged, not sent."""
    if isinstance(cause, UnicodeDecodeError):
        return "it is not UTF-8 text"
    if isinstance(cause, RecursionError):
        return "it is nested too deeply"
    log.info("unreadable request body: %s: %s", type(cause).__name__, cause)
    if isinstance(cause, ValueError) and "digits" in str(cause):
        return "it has a whole number with too many digits to read"
    return "it is not JSON that can be read"


# methods an API route may answer, tried in turn to tell a wrong method (405) from a wrong path (404)
_METHODS = ("GET", "POST", "PUT", "PATCH", "DELETE")


def _api_methods(request: Request) -> list[str]:
    """Methods some API route answers on the request's path."""
    routes = [r for r in request.app.routes if not isinstance(r, Mount)]
    return [m for m in _METHODS
            if any(r.matches({**request.scope, "method": m})[0] == Match.FULL for r in routes)]


def _unrouted(request: Request) -> bool:
    """True when no API route took the request: the page's static files (mounted at /) answered it."""
    return not any(r.matches(request.scope)[0] == Match.FULL for r in request.app.routes if not isinstance(r, Mount))


def _no_api_route(request: Request) -> JSONResponse:
    """An /api/ request no route takes (the static files at / would answer a bare 404 or a 405 allowing
    GET): 405 with ``Allow`` when the path exists for other methods (``GET /api/tryon``), else 404."""
    allowed = _api_methods(request)
    if allowed:
        return JSONResponse({"detail": f"{request.method} is not allowed on {request.url.path}: use "
                                       f"{' or '.join(allowed)} (see /api/docs)"},
                            status_code=405, headers={"Allow": ", ".join(allowed)})
    return JSONResponse({"detail": f"no API route {request.method} {request.url.path} (see /api/docs)"},
                        status_code=404)


def install(app: FastAPI) -> None:
    """Register the handlers on ``app``."""
    app.add_exception_handler(RequestValidationError, validation_error)
    app.add_exception_handler(StarletteHTTPException, http_error)
