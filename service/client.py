"""Sending CLI work to a running phongray service (standard library only)."""

from __future__ import annotations

import http.client
import json
import os
import urllib.error
import urllib.parse
import urllib.request
import uuid
from typing import Any


class ServerError(Exception):
    """The server answered with an error, or could not be reached."""

    def __init__(
        self, message: str, status: int = 0, body: Any = None, headers: dict[str, str] | None = None, lost: bool = False
    ):
        super().__init__(message)
        self.status, self.body, self.headers = status, body, headers or {}
        #: the connection was refused, reset or closed before an answer (a server worker restarting): worth a
        #: retry, unlike a timeout or an answer
        self.lost = lost

    @property
    def problems(self) -> str | None:
        """The scene problems of a 422 answer as ``path: message; …``, or None when it lists none."""
        body = self.body
        if not (isinstance(body, dict) and body.get("errors")):
            return None
        return "; ".join(f"{e['path']}: {e['message']}" if e.get("path") else e["message"] for e in body["errors"])

    @property
    def part(self) -> str | None:
        """The form part a /grade error concerns (``"image"``), when the server says."""
        return self.body.get("part") if isinstance(self.body, dict) else None

    @property
    def detail(self) -> str:
        """What the server said: its problems, its ``detail``, or the error itself."""
        if self.problems is not None:
            return self.problems
        return str(self.body.get("detail", self.body)) if isinstance(self.body, dict) else str(self)

    @property
    def ta_side(self) -> bool:
        """Whether the fault is the caller's, not the input's: the server cannot be reached, refuses the key
        (401, 403), or failed itself (a 5xx other than a 503 to wait out)."""
        return self.status in (0, 401, 403) or (self.status >= 500 and self.status != 503)

    @property
    def retry_after(self) -> float | None:
        """Seconds the server asked to wait (a 503's ``Retry-After``), or None."""
        value = {k.lower(): v for k, v in self.headers.items()}.get("retry-after")
        try:
            return max(0.0, float(value)) if value is not None else None
        except ValueError:
            return None


def base_url(server: str) -> str:
    """``localhost:8000`` → ``http://localhost:8000``; no trailing slash.  A ServerError (the caller's) for a URL
    that names no server: an empty one, an unclosed ``[`` of an IPv6 address, a port beyond 65535, a scheme other
    than http or https."""
    server = server.strip()
    url = (server if "://" in server else f"http://{server}").rstrip("/")
    try:
        parts = urllib.parse.urlsplit(url)
        parts.port  # noqa: B018 (read for its ValueError: a port that is not 0–65535)
    except ValueError as exc:
        raise ServerError(f"--server: {server!r} is not a URL ({exc})") from None
    if parts.scheme not in ("http", "https") or not parts.hostname:
        raise ServerError(f"--server: {server!r} is not the http:// or https:// URL of a server")
    return url


def _call(request: urllib.request.Request, timeout: float, api_key: str | None) -> tuple[int, bytes, dict[str, str]]:
    key = api_key if api_key is not None else os.environ.get("PHONGRAY_API_KEY", "")
    if key:
        request.add_header("Authorization", f"Bearer {key}")
    try:
        with urllib.request.urlopen(request, timeout=timeout) as res:
            return res.status, res.read(), dict(res.headers)
    except urllib.error.HTTPError as exc:
        with exc:
            raw = exc.read()
        try:
            body: Any = json.loads(raw)
        except ValueError:
            body = raw.decode("utf-8", "replace")
        detail = body.get("detail", body) if isinstance(body, dict) else body
        raise ServerError(f"server answered {exc.code}: {detail}", exc.code, body, dict(exc.headers or {})) from None
    except (urllib.error.URLError, OSError, http.client.HTTPException, ValueError) as exc:
        reason = getattr(exc, "reason", exc)  # (ValueError: a URL urllib cannot use, such as port 99999)
        lost = isinstance(reason, (ConnectionError, http.client.HTTPException))
        raise ServerError(f"cannot reach {request.full_url}: {reason or type(exc).__name__}", lost=lost) from None


def get(server: str, path: str, timeout: float = 30, api_key: str | None = None) -> bytes:
    """GET a path of the service (with the key, as :func:`post_json`)."""
    return _call(urllib.request.Request(base_url(server) + path), timeout, api_key)[1]


def check(server: str, api_key: str | None = None) -> None:
    """Before a batch: the service answers and takes the key (a ServerError with ``ta_side`` if not)."""
    get(server, "/healthz", api_key=api_key)
    get(server, "/schema", api_key=api_key)  # every endpoint but /healthz needs the key, when it has one


def post_json(
    server: str,
    path: str,
    body: bytes,
    query: dict[str, Any] | None = None,
    timeout: float = 600,
    api_key: str | None = None,
) -> bytes:
    """POST a JSON body; ``api_key`` (default: ``$PHONGRAY_API_KEY``) goes as ``Authorization: Bearer``."""
    params = "&".join(f"{k}={v}" for k, v in (query or {}).items() if v is not None)
    url = base_url(server) + path + (f"?{params}" if params else "")
    req = urllib.request.Request(url, data=body, method="POST", headers={"content-type": "application/json"})
    return _call(req, timeout, api_key)[1]


def post_form(
    server: str,
    path: str,
    fields: dict[str, bytes | str],
    files: dict[str, tuple[str, bytes, str]],
    query: dict[str, Any] | None = None,
    timeout: float = 600,
    api_key: str | None = None,
) -> bytes:
    boundary = uuid.uuid4().hex
    parts: list[bytes] = []
    for name, value in fields.items():
        data = value.encode() if isinstance(value, str) else value
        parts.append(f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"\r\n\r\n'.encode() + data + b"\r\n")
    for name, (filename, data, kind) in files.items():
        head = (
            f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"; filename="{filename}"\r\n'
            f"Content-Type: {kind}\r\n\r\n"
        )
        parts.append(head.encode() + data + b"\r\n")
    body = b"".join(parts) + f"--{boundary}--\r\n".encode()
    params = "&".join(f"{k}={v}" for k, v in (query or {}).items() if v is not None)
    url = base_url(server) + path + (f"?{params}" if params else "")
    req = urllib.request.Request(
        url, data=body, method="POST", headers={"content-type": f"multipart/form-data; boundary={boundary}"}
    )
    return _call(req, timeout, api_key)[1]
