"""Bearer-token protection for everything that changes state.

Reading is open (the service binds loopback by default); planning, uploading,
starting, aborting and registering vehicles need the token. If none is configured,
the first start makes one and keeps it in the data directory, readable by its owner only.
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path
from typing import Annotated

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from gcs.service.settings import Settings

bearer = HTTPBearer(auto_error=False, description="the service's token (see its start-up log)")


def ensure_token(settings: Settings) -> tuple[str, Path | None]:
    """The token and the file it lives in (None when it came from the settings)."""
    if settings.token:
        return settings.token, None
    path = settings.token_file
    if path.exists():
        return path.read_text().strip(), path
    path.parent.mkdir(parents=True, exist_ok=True)
    token = secrets.token_urlsafe(24)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(token + "\n")
    return token, path


class TokenRefused(Exception):
    """401 (no bearer token) or 403 (a wrong one), with the header that says which scheme."""

    def __init__(self, status_code: int, detail: str) -> None:
        super().__init__(detail)
        self.status_code, self.detail = status_code, detail
        self.headers = {"WWW-Authenticate": "Bearer"}


def check_bearer(authorization: str | None, expected: str) -> None:
    """The one token check: the request guard runs it before any byte of a body is read,
    the routes' dependency (which also puts the scheme in the OpenAPI document) again."""
    scheme, _, given = (authorization or "").partition(" ")
    if scheme.lower() != "bearer" or not given.strip():
        raise TokenRefused(
            status.HTTP_401_UNAUTHORIZED,
            "this request changes state: send 'Authorization: Bearer <token>'",
        )
    if not secrets.compare_digest(given.strip().encode(), expected.encode()):
        raise TokenRefused(status.HTTP_403_FORBIDDEN, "the bearer token is wrong")


async def require_token(
    request: Request,
    _: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)],
) -> None:
    try:
        check_bearer(request.headers.get("authorization"), request.app.state.token)
    except TokenRefused as refused:
        raise HTTPException(refused.status_code, refused.detail, refused.headers) from None
