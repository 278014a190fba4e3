"""Figures a camera worker keeps of itself for ``/metrics``: gathered where they happen
and sent with its ``status``, so the server reports what the camera processes measured."""

from __future__ import annotations

import bisect

DETECT_BUCKETS = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.25, 1.0)
"""Upper bounds (seconds) of the detection-time histogram's buckets: a 320-wide frame takes
about a millisecond, a full-size 4K one tens."""


class TimeHistogram:
    """Durations counted into ``DETECT_BUCKETS`` (and above the last), with their sum."""

    def __init__(self) -> None:
        self._counts = [0] * (len(DETECT_BUCKETS) + 1)
        self._sum = 0.0

    def observe(self, seconds: float) -> None:
        self._counts[bisect.bisect_left(DETECT_BUCKETS, seconds)] += 1
        self._sum += seconds

    def wire(self) -> dict[str, list[int] | float]:
        """``counts``: per bucket, the last one above every bound; ``sum``: seconds."""
        return {"counts": list(self._counts), "sum": round(self._sum, 6)}
