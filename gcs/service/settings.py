"""Service settings: command-line flags override environment variables (`MVO_GCS_*`)."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="MVO_GCS_", extra="ignore")

    host: str = Field(default="127.0.0.1", description="bind address; loopback unless asked")
    port: int = Field(default=8000, ge=0, le=65535)
    data_dir: Path = Field(default=Path("mvo-gcs-data"), description="SQLite file and token")
    database_url: str | None = Field(
        default=None, description="SQLAlchemy URL; default: SQLite under data_dir"
    )
    token: str | None = Field(default=None, description="bearer token for mutating requests")
    show_token: bool = Field(default=False, description="print the token itself at start-up")
    max_body_bytes: int = Field(default=1_000_000, ge=1_000)
    body_timeout_s: float = Field(
        default=10.0, gt=0, le=600, description="a request body must arrive within this"
    )
    allowed_hosts: list[str] = Field(
        default_factory=lambda: ["127.0.0.1", "localhost", "::1"],
        description="Host header names (and WebSocket origins) the service answers to; "
        "the bind address is added when it is a specific one",
    )
    plan_workers: int = Field(
        default=2,
        ge=0,
        le=64,
        description="planning processes; 0 plans in a thread of the service (tests, demos: "
        "it shares the event loop's processor time, so not beside real vehicles)",
    )
    dask_scheduler: str = Field(
        default="",
        description="plan on the Dask cluster at this address (tcp://host:8786) instead of "
        "local processes (plan_workers then unused); needs the distributed package, and "
        "mvo-gcs on every worker",
    )
    inline_plan_wait_s: float = Field(
        default=2.0, ge=0, le=60, description="how long a plan request waits before it answers 202"
    )
    max_plan_evaluations: int = Field(
        default=2_000_000,
        ge=1,
        description="cap on population x iterations x candidates of a request without a time "
        "budget",
    )
    max_plan_seconds: float = Field(
        default=120.0, gt=0, description="cap on the time budget of one plan request"
    )
    live_rate_hz: float = Field(default=10.0, gt=0, le=50)
    fence_action: int = Field(
        default=1,
        ge=0,
        le=5,
        description="ArduCopter's FENCE_ACTION set on the vehicles of a flight on a geographic "
        "scenario: 0 report only, 1 RTL or land, 2 land, 3 SmartRTL or RTL or land, 4 brake "
        "or land, 5 SmartRTL or land",
    )
    link_loss_brake_s: float = Field(
        default=2.0,
        ge=0,
        le=120,
        description="a vehicle of a flight that has not heard the service for this many "
        "seconds brakes (ArduCopter's GCS failsafe: FS_GCS_ENABLE 7, set at upload); 0 "
        "leaves the vehicles' own failsafe settings as they are",
    )
    event_memory_rows: int = Field(
        default=10_000,
        ge=1,
        le=10_000_000,
        description="flight events kept in memory while storage is behind; beyond them they "
        "wait in <data dir>/event-spill.jsonl, none dropped",
    )
    max_live_sockets: int = Field(
        default=64, ge=1, le=10_000, description="live WebSockets open at once, in all"
    )
    max_live_sockets_per_subject: int = Field(
        default=16, ge=1, le=10_000, description="live WebSockets open at once on one flight or job"
    )
    max_ws_message_bytes: int = Field(
        default=4096,
        ge=125,
        le=16 * 2**20,
        description="the largest WebSocket message a client may send (they only receive)",
    )
    http_header_timeout_s: float = Field(
        default=10.0,
        gt=0,
        le=300,
        description="a connection whose request headers are not in by then is closed",
    )
    max_connections: int = Field(
        default=200, ge=8, le=100_000, description="HTTP connections at once; beyond: 503"
    )
    max_connections_per_client: int = Field(
        default=32, ge=1, le=100_000, description="HTTP connections one address may hold"
    )
    discovery_url: str = Field(
        default="udpin:127.0.0.1:14550",
        description="UDP port where vehicles that announce themselves are heard (as "
        "QGroundControl listens); empty: no discovery",
    )
    discovery_forget_s: float = Field(
        default=30.0,
        gt=0,
        le=86_400,
        description="a vehicle heard on the listening port, not registered and silent this "
        "long, is no longer listed",
    )
    console_tile_url: str = Field(
        default="",
        max_length=500,
        description="map tiles under the console's grid, as a {z}/{x}/{y} URL template; "
        "empty: a plain offline grid",
    )
    listen_beyond_loopback: bool = Field(
        default=False,
        description="allow listening (udpin:) on addresses other than loopback, for the "
        "discovery port and for registered vehicles",
    )

    service_id: str = Field(
        default="",
        max_length=200,
        description="this service's name among the services sharing a database (the lease "
        "holder of its flights); default: host name, port and a random suffix per start",
    )
    public_url: str = Field(
        default="",
        max_length=500,
        description="the base URL other services name when they refuse a request for a "
        "flight this one controls; default: http://host:port",
    )
    lease_s: float = Field(
        default=3.0,
        gt=0,
        le=300,
        description="how long a flight's or job's lease lasts unrenewed: a service that "
        "stops renewing (killed) loses its flights to another this long after",
    )
    lease_renew_s: float = Field(
        default=1.0, gt=0, le=100, description="how often a service renews its leases"
    )
    resume_taken_over: bool = Field(
        default=True,
        description="resume a flight taken over in the air from a service that died, as "
        "soon as every vehicle is heard (each stopped first, then let go in the passing "
        "order); false: it stays interrupted, its missions paused, for the operator",
    )

    @property
    def host_names(self) -> frozenset[str]:
        names = {name.strip("[]").lower() for name in self.allowed_hosts}
        if self.host not in ("0.0.0.0", "::", ""):
            names.add(self.host.strip("[]").lower())
        return frozenset(names)

    @property
    def resolved_database_url(self) -> str:
        return self.database_url or f"sqlite:///{(self.data_dir / 'mvo-gcs.db').resolve()}"

    @property
    def token_file(self) -> Path:
        return self.data_dir / "token"
