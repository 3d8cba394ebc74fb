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


async def require_token(
    request: Request,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)],
) -> None:
    expected: str = request.app.state.token
    if credentials is None or credentials.scheme.lower() != "bearer":
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED,
            "this request changes state: send 'Authorization: Bearer <token>'",
            headers={"WWW-Authenticate": "Bearer"},
        )
    if not secrets.compare_digest(credentials.credentials.encode(), expected.encode()):
        raise HTTPException(
            status.HTTP_403_FORBIDDEN,
            "the bearer token is wrong",
            headers={"WWW-Authenticate": "Bearer"},
        )
