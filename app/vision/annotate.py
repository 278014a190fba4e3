"""Draw what was found: red boxes, track ids, trails and speed labels."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from app.vision.detections import Detection
from app.vision.preprocess import to_size
from app.vision.types import GrayImage, Image, Mask

RED = (0, 0, 255)
WHITE = (255, 255, 255)
TRAIL = (0, 200, 255)


@dataclass(frozen=True)
class Annotator:
    thickness: int = 2
    show_speed: bool = True

    def __call__(
        self,
        frame: Image,
        detections: Sequence[Detection],
        trails: Mapping[int, Sequence[tuple[float, float]]] | None = None,
    ) -> Image:
        """A copy of the frame with every detection drawn on it."""
        canvas = frame.copy() if frame.ndim == 3 else cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
        font_scale = max(0.35, min(canvas.shape[1] / 1280.0, 1.0))
        for points in (trails or {}).values():
            if len(points) >= 2:
                polyline = np.round(np.asarray(points)).astype(np.int32).reshape(-1, 1, 2)
                cv2.polylines(canvas, [polyline], False, TRAIL, 1, cv2.LINE_AA)
        for det in detections:
            b = det.box
            cv2.rectangle(canvas, (b.x, b.y), (b.x + b.w - 1, b.y + b.h - 1), RED, self.thickness)
            label = self._label(det)
            if label:
                (tw, th), base = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, font_scale, 1)
                top = max(0, b.y - th - base - 2)
                cv2.rectangle(canvas, (b.x, top), (b.x + tw + 4, top + th + base + 2), RED, -1)
                cv2.putText(
                    canvas,
                    label,
                    (b.x + 2, top + th + 1),
                    cv2.FONT_HERSHEY_SIMPLEX,
                    font_scale,
                    WHITE,
                    1,
                    cv2.LINE_AA,
                )
        return canvas

    def _label(self, det: Detection) -> str:
        parts = [] if det.track_id is None else [f"#{det.track_id}"]
        if self.show_speed and det.track_id is not None:
            if det.speed_m_s is not None:
                parts.append(f"{det.speed_m_s * 3.6:.1f} km/h")
            else:
                parts.append(f"{det.speed_px_s:.0f} px/s")
        return " ".join(parts)


def overlay_mask(frame: Image, mask: Mask, color: tuple[int, int, int] = RED) -> Image:
    """The binary motion mask tinted over the picture (the "how sensitive" view)."""
    canvas = frame.copy() if frame.ndim == 3 else cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    mask = to_size(mask, (canvas.shape[1], canvas.shape[0]))
    tint = np.zeros_like(canvas)
    tint[:] = color
    blended = cv2.addWeighted(canvas, 0.5, tint, 0.5, 0)
    np.copyto(canvas, blended, where=(mask > 0)[..., None])
    return canvas


def difference_picture(difference: GrayImage, size: tuple[int, int]) -> GrayImage:
    """The paper's difference image for a snapshot: stretched to full contrast, at ``size``."""
    stretched = cv2.normalize(difference, np.empty_like(difference), 0, 255, cv2.NORM_MINMAX)
    return to_size(stretched, size)


def status_card(title: str, detail: str, size: tuple[int, int] = (640, 360)) -> Image:
    """A dark picture saying why there is no picture: ``title`` large, ``detail`` wrapped
    below it (for a stream whose camera is down)."""
    width, height = size
    margin, first_line, line_height = 24, 110, 26
    font = cv2.FONT_HERSHEY_SIMPLEX
    card = np.full((height, width, 3), 32, np.uint8)
    cv2.putText(card, title, (margin, 64), font, 1.2, WHITE, 2, cv2.LINE_AA)
    line, lines = "", []
    for word in detail.split():
        wider = f"{line} {word}".strip()
        if line and cv2.getTextSize(wider, font, 0.6, 1)[0][0] > width - 2 * margin:
            lines.append(line)
            wider = word
        line = wider
    lines.append(line)
    for row, text in enumerate(lines[: (height - first_line) // line_height]):
        origin = (margin, first_line + line_height * row)
        cv2.putText(card, text, origin, font, 0.6, WHITE, 1, cv2.LINE_AA)
    return card
