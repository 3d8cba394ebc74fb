"""Prometheus metrics of one service instance (its own registry, so tests can run several)."""

from __future__ import annotations

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest


class ServiceMetrics:
    def __init__(self) -> None:
        self.registry = CollectorRegistry()
        self.plans = Counter(
            "mvo_gcs_plans", "plans finished, by outcome", ["outcome"], registry=self.registry
        )
        self.plan_seconds = Histogram(
            "mvo_gcs_plan_seconds",
            "wall time of a plan request, queueing included",
            buckets=(0.1, 0.25, 0.5, 1, 2, 5, 10, 30, 60, 300),
            registry=self.registry,
        )
        self.uploads = Counter(
            "mvo_gcs_uploads", "mission uploads, by outcome", ["outcome"], registry=self.registry
        )
        self.upload_retries = Counter(
            "mvo_gcs_upload_retries", "mission-protocol messages re-sent", registry=self.registry
        )
        self.link_up = Gauge(
            "mvo_gcs_vehicle_link_up",
            "1 while a vehicle is heard",
            ["vehicle"],
            registry=self.registry,
        )
        self.ignored_packets = Gauge(
            "mvo_gcs_vehicle_ignored_packets",
            "packets dropped on a vehicle's connection: from a wrong address, or unsigned",
            ["vehicle"],
            registry=self.registry,
        )
        self.loop_lag = Histogram(
            "mvo_gcs_event_loop_lag_seconds",
            "how late the event loop ran a 10 ms timer (a stall delays every vehicle link)",
            buckets=(0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.25, 1.0),
            registry=self.registry,
        )
        self.replans = Counter(
            "mvo_gcs_live_replans",
            "live replanning requests, by outcome",
            ["outcome"],
            registry=self.registry,
        )
        self.events_pending = Gauge(
            "mvo_gcs_events_pending",
            "flight events recorded and not yet stored (in memory, being written or spilled)",
            registry=self.registry,
        )
        self.events_spilled = Gauge(
            "mvo_gcs_events_spilled",
            "of them, those in the spill file: storage fell behind by more than memory holds",
            registry=self.registry,
        )
        self.events_oldest_pending = Gauge(
            "mvo_gcs_events_oldest_pending_seconds",
            "how long ago the oldest flight event not yet stored was recorded",
            registry=self.registry,
        )
        self.events_written = Counter(
            "mvo_gcs_events_written", "flight events stored", registry=self.registry
        )
        self.event_store_lag = Histogram(
            "mvo_gcs_event_store_lag_seconds",
            "from a flight event's recording to the commit of the transaction that stored it",
            buckets=(
                *(0.001, 0.002, 0.005, 0.0075, 0.01, 0.015, 0.02, 0.03, 0.05, 0.075, 0.1),
                *(0.15, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60),
            ),
            registry=self.registry,
        )
        self.events_spill_appends = Counter(
            "mvo_gcs_events_spill_appends",
            "flight events appended to the spill file since the start (storage was behind by "
            "more than memory holds)",
            registry=self.registry,
        )
        self.event_store_failures = Counter(
            "mvo_gcs_event_store_failures",
            "writes of a batch of flight events that storage refused (each is tried again)",
            registry=self.registry,
        )
        self.events_discarded = Counter(
            "mvo_gcs_events_discarded",
            "flight events left out: their flight was deleted before they were stored, or a "
            "crash cut their line in the spill file short",
            registry=self.registry,
        )
        self.live_dropped = Counter(
            "mvo_gcs_live_messages_dropped",
            "live-stream messages dropped for a WebSocket client too slow to take them "
            "(the client is told how many)",
            registry=self.registry,
        )

    def render(self) -> bytes:
        return generate_latest(self.registry)
