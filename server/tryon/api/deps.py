"""Shared FastAPI dependencies (``Annotated`` aliases): settings, the catalogue, the admin check; and
``app_state``, the one way an app's shared objects are made on first use."""

from __future__ import annotations

import secrets
import threading
from typing import Annotated, Any, Callable, TypeVar

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from tryon.config import Settings
from tryon.garment.catalogue import Catalogue

T = TypeVar("T")

# Guards the first creation of an app's shared objects (catalogue, pool, result cache); re-entrant so
# that one factory may ask for another.
_state_lock = threading.RLock()


def app_state(app: Any, name: str, create: Callable[[], T]) -> T:
    """``app.state.<name>``, made by ``create()`` on first use (once, even with concurrent requests)."""
    value = getattr(app.state, name, None)
    if value is None:
        with _state_lock:
            value = getattr(app.state, name, None)
            if value is None:
                value = create()
                setattr(app.state, name, value)
    return value


def get_settings(request: Request) -> Settings:
    """The app's settings (``create_app`` stores them on ``app.state``)."""
    return request.app.state.settings


SettingsDep = Annotated[Settings, Depends(get_settings)]


def get_catalogue(request: Request) -> Catalogue:
    """The one Catalogue of this app, opened on first use over ``settings.data_dir``."""
    app = request.app
    return app_state(app, "catalogue", lambda: Catalogue(app.state.settings.data_dir))


CatalogueDep = Annotated[Catalogue, Depends(get_catalogue)]

_bearer = HTTPBearer(auto_error=False)


def require_admin(
    settings: SettingsDep,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
) -> None:
    """Catalogue writes need ``Authorization: Bearer <TRYON_ADMIN_TOKEN>``.

    No token configured: 403 (writes are disabled). Missing or wrong token: 401."""
    if not settings.admin_token:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "catalogue writes are disabled: set TRYON_ADMIN_TOKEN")
    if credentials is None or credentials.scheme.lower() != "bearer":
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "missing admin token: send Authorization: Bearer <token>",
                            headers={"WWW-Authenticate": "Bearer"})
    if not secrets.compare_digest(credentials.credentials.encode(), settings.admin_token.encode()):
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "wrong admin token", headers={"WWW-Authenticate": "Bearer"})


AdminDep = Annotated[None, Depends(require_admin)]
