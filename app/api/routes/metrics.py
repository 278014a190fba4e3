"""``GET /metrics``: Prometheus' text format, read from what the server and its camera
processes report at the moment of the scrape (nothing is sampled in between)."""

from __future__ import annotations

from collections.abc import Iterator

from fastapi import APIRouter, Request, Response
from prometheus_client import CONTENT_TYPE_LATEST, CollectorRegistry, generate_latest
from prometheus_client.core import (
    CounterMetricFamily,
    GaugeMetricFamily,
    HistogramMetricFamily,
    Metric,
)

from app.api.services import Services, services
from app.workers.figures import DETECT_BUCKETS

router = APIRouter()


class VigilCollector:
    """Every figure of ``/metrics``, gathered from ``services`` at each scrape."""

    def __init__(self, svc: Services) -> None:
        self.services = svc

    def collect(self) -> Iterator[Metric]:
        yield from self._cameras()
        svc = self.services
        events_open = GaugeMetricFamily("vigil_events_open", "Events that have not ended.")
        events_open.add_metric([], svc.database.open_events())
        yield events_open
        snapshots = GaugeMetricFamily("vigil_snapshots_bytes", "Disk space the snapshots use.")
        snapshots.add_metric([], svc.database.snapshot_bytes())
        yield snapshots
        clips = GaugeMetricFamily("vigil_clips_bytes", "Disk space the event clips use.")
        clips.add_metric([], svc.database.clip_bytes())
        yield clips
        yield from self._notifications()
        mqtt = GaugeMetricFamily(
            "vigil_mqtt_connected", "1 while connected to the MQTT broker (none without one)."
        )
        if svc.mqtt is not None:
            mqtt.add_metric([], int(svc.mqtt.connected))
        yield mqtt

    def _notifications(self) -> Iterator[Metric]:
        labels = ["target", "service"]
        sent = CounterMetricFamily(
            "vigil_notifications_sent", "Messages a target took.", labels=labels
        )
        failed = CounterMetricFamily(
            "vigil_notifications_failed",
            "Messages a target did not take, after every retry (or dropped from its queue).",
            labels=labels,
        )
        for target_id, counts in self.services.notifier.counters().items():
            target = [str(target_id), str(counts["service"])]
            sent.add_metric(target, counts["sent"])
            failed.add_metric(target, counts["failed"])
        yield from (sent, failed)

    def _cameras(self) -> Iterator[Metric]:
        labels = ["camera"]
        info = GaugeMetricFamily("vigil_camera_info", "A camera's name.", labels=["camera", "name"])
        up = GaugeMetricFamily("vigil_camera_up", "1 while the camera sends frames.", labels=labels)
        fps = GaugeMetricFamily("vigil_camera_fps", "Frames a second, as measured.", labels=labels)
        active = GaugeMetricFamily("vigil_camera_active", "1 while activated.", labels=labels)
        viewers = GaugeMetricFamily("vigil_viewers", "Live streams open.", labels=labels)
        frames = CounterMetricFamily(
            "vigil_camera_frames", "Frames read since its worker started.", labels=labels
        )
        alarms = CounterMetricFamily(
            "vigil_alarms", "Alarms raised since its worker started.", labels=labels
        )
        detect = HistogramMetricFamily(
            "vigil_camera_detect_seconds",
            "The detection pipeline's time per frame.",
            labels=labels,
        )
        for camera in self.services.cameras.all():
            status, camera_id = camera.status(), str(camera.camera_id)
            info.add_metric([camera_id, str(camera.row.get("name", ""))], 1)
            up.add_metric([camera_id], int(status["state"] == "live"))
            fps.add_metric([camera_id], status["fps"])
            active.add_metric([camera_id], int(status["active"]))
            viewers.add_metric([camera_id], status["viewers"])
            frames.add_metric([camera_id], status["frames"])
            alarms.add_metric([camera_id], status["alarms"])
            histogram = status["detect_seconds"]
            detect.add_metric([camera_id], _buckets(histogram["counts"]), histogram["sum"])
        yield from (info, up, fps, active, viewers, frames, alarms, detect)


def _buckets(counts: list[int]) -> list[tuple[str, float]]:
    """Prometheus' cumulative buckets from the counts per bucket (the last above all)."""
    bounds = [*(repr(bound) for bound in DETECT_BUCKETS), "+Inf"]
    total, cumulative = 0, []
    for bound, count in zip(bounds, counts, strict=True):
        total += count
        cumulative.append((bound, float(total)))
    return cumulative


@router.get("/metrics", include_in_schema=False)
def metrics(request: Request) -> Response:
    """Prometheus' text format. With a password set, it needs it as any API call does
    (HTTP basic auth, which Prometheus' ``basic_auth`` sends)."""
    registry = CollectorRegistry(auto_describe=False)
    registry.register(VigilCollector(services(request)))
    return Response(generate_latest(registry), media_type=CONTENT_TYPE_LATEST)
