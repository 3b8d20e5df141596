"""Every limit and knob of phongray, in one object read from the environment (pydantic-settings).

Each field can be set by an environment variable ``PHONGRAY_<NAME>`` (upper
case), for example ``PHONGRAY_MAX_PIXELS=1000000``.  The service reads all of
them; the command line reads ``api_key`` and ``cluster`` (the defaults of
``--api-key`` and ``--cluster``) and ``max_image_bytes`` (the most it reads of
a submitted image).
"""

from __future__ import annotations

from pydantic import ValidationError
from pydantic_settings import BaseSettings, SettingsConfigDict

from .render.cluster import CLUSTER_WAIT


class SettingsError(ValueError):
    """An environment variable that does not hold a value of its setting's type."""


class Settings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="PHONGRAY_", frozen=True, extra="ignore")

    max_body_bytes: int = 8 * 1024 * 1024  # request body
    max_image_bytes: int = 16 * 1024 * 1024  # submitted PNG in /grade (and read by grade and grade-class)
    max_pixels: int = 4096 * 4096  # width × height
    max_samples: int = 8  # n of the n×n sub-sample grid
    max_depth: int = 16
    max_objects: int = 10_000
    max_triangles: int = 250_000
    max_vertices: int = 200_000  # mesh vertices in all (and as many normals)
    max_materials: int = 1_000
    max_lights: int = 1_024  # entries of "lights", ambient ones included
    max_light_samples: int = 1_024  # directional + point + spot lights + all area-light samples
    max_cost: float = (
        1e8  # ray work a render may do, counted as it runs (service/admission/limits.py, docs/cost-model.md)
    )
    max_ray_bytes: int = 1024 * 1024 * 1024  # memory a render's rays in flight may hold
    max_concurrent_renders: int = 2  # renders at once per worker process; more wait their turn ...
    queue_wait: float = 60.0  # ... at most this many seconds, then get 503 with a Retry-After of the queue
    render_threads: int = 0  # threads per render; 0 means every core
    render_timeout: float = 120.0  # seconds; a longer render is stopped and answered with 503
    cache_bytes: int = 64 * 1024 * 1024  # reference renders kept for /grade and /render
    retry_after: int = 1  # seconds, in the Retry-After header of a 503
    api_key: str = ""  # when set, every endpoint but /healthz needs it (and --server sends it)
    header_timeout: float = 10.0  # seconds a client has to send a request line and its headers
    body_timeout: float = 10.0  # seconds of grace for a request body ...
    body_min_rate: int = 65_536  # ... which must then keep arriving at this many bytes per second (else 408)
    keep_alive: float = 5.0  # seconds an idle kept-alive connection stays open
    balance_patience: float = 0.02  # seconds a worker of serve --workers N stands aside for the one whose turn it is
    max_connections: int = 1_000  # open connections per worker process; beyond it, 503
    max_buffered_bytes: int = 96 * 1024 * 1024  # request bodies one worker process holds at once ...
    buffer_wait: float = 30.0  # ... beyond which a body waits this many seconds for room, then gets 503
    max_answer_bytes: int = 1024 * 1024 * 1024  # image answers (renders, passes, heat-maps) a worker holds
    send_timeout: float = 30.0  # seconds a chunk of an answer may wait for the client to read it; then dropped
    cluster: str = ""  # a Dask scheduler (tcp://HOST:PORT): renders go to its workers instead of this process
    cluster_wait: float = CLUSTER_WAIT  # seconds to wait for a cluster's first worker before giving up

    @classmethod
    def from_env(cls) -> Settings:
        """The settings of the environment; a value of the wrong type is one :class:`SettingsError` line."""
        try:
            return cls()
        except ValidationError as exc:
            err = exc.errors(include_url=False)[0]
            name = f"PHONGRAY_{str(err['loc'][0]).upper()}"
            raise SettingsError(f"{name}: {err['msg']}, got {err.get('input')!r}") from None
