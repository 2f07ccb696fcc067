"""Prometheus metrics of one application (its own registry, so that several apps in one
process, as in the tests, do not collide), served at ``/metrics`` in the text format."""

from __future__ import annotations

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest
from prometheus_client.exposition import CONTENT_TYPE_LATEST

__all__ = ["CONTENT_TYPE_LATEST", "Metrics"]

_BUCKETS = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 120.0)


class Metrics:
    def __init__(self) -> None:
        self.registry = CollectorRegistry()
        self.requests = Counter(
            "linkage_requests", "HTTP requests answered, by route template and status",
            ["method", "route", "status"], registry=self.registry)
        self.latency = Histogram(
            "linkage_request_duration_seconds", "Time to answer a request, by route template",
            ["route"], buckets=_BUCKETS, registry=self.registry)
        self.in_flight = Gauge(
            "linkage_requests_in_flight", "Requests being answered", registry=self.registry)
        self.engine_events = Counter(
            "linkage_engine_events",
            "Engine requests not answered by the engine: time_limit (stopped at "
            "LINKAGE_TIME_LIMIT_S), worker_failed (the worker died), busy (queue full), "
            "pool_replaced (a worker died while idle and the pool was replaced)",
            ["event"], registry=self.registry)
        for event in ("time_limit", "worker_failed", "busy", "pool_replaced"):
            self.engine_events.labels(event=event)

    def observe(self, method: str, route: str, status: int, seconds: float) -> None:
        self.requests.labels(method=method, route=route, status=str(status)).inc()
        self.latency.labels(route=route).observe(seconds)

    def engine_event(self, event: str) -> None:
        self.engine_events.labels(event=event).inc()

    def exposition(self) -> bytes:
        return generate_latest(self.registry)
