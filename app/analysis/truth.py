"""Ground truth for `--truth`: CDnet folders, single mask files, or box JSON.

* A CDnet sequence folder (or its ``groundtruth/`` folder): ``gtNNNNNN.png``
  label images (0 static, 50 shadow, 85 outside ROI, 170 unknown, 255 moving),
  with ``temporalROI.txt`` and ``ROI.bmp``/``ROI.jpg`` honoured when present.
* A single mask image whose name ends in its frame number
  (``hand_segmented_00247.png``, Wallflower style): 255 = moving.
* A JSON file of boxes per frame (``docs/truth-format.md``)::

      {"frames": {"0": [[x, y, w, h], ...], "1": [...]}}
      {"frames": [{"frame": 0, "boxes": [{"x": 1, "y": 2, "w": 3, "h": 4}]}]}

Frame numbers in mask names are matched to the input: by number when the
input's own frame files carry numbers (CDnet ``inNNNNNN.jpg``), else by order
(the first mask is frame 0).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from app.sources.files import frame_number
from app.vision.detections import Box
from app.vision.types import Mask

MASK_SUFFIXES = (".png", ".bmp", ".jpg", ".jpeg", ".tif", ".tiff", ".pgm")


ASPECT_TOLERANCE = 0.02
"""Labels whose width/height differs from the input's by more than this are another scene's."""


class TruthError(ValueError):
    """The truth file or folder cannot be read; the message says why."""


@dataclass
class Truth:
    """Ground truth keyed by 0-based input frame index."""

    kind: str
    boxes: dict[int, list[Box]] = field(default_factory=dict)
    mask_paths: dict[int, Path] = field(default_factory=dict)
    roi: Mask | None = None
    source: str = ""

    @property
    def frames(self) -> list[int]:
        return sorted(set(self.boxes) | set(self.mask_paths))

    def mask(self, frame: int) -> Mask | None:
        path = self.mask_paths.get(frame)
        if path is None:
            return None
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise TruthError(f"cannot read ground-truth image {path}")
        return image

    def check_size(self, size: tuple[int, int]) -> None:
        """Refuse labels of another shape than the input's ``(width, height)``.

        Labels at another scale are rescaled when scored; another aspect ratio
        means the truth belongs to another video.
        """
        first = self.frames[0] if self.frames else None
        label = self.mask(first) if first is not None else None
        pictures = [("labels", label), ("ROI", self.roi)]
        for what, picture in pictures:
            if picture is None:
                continue
            height, width = picture.shape[:2]
            if abs(width * size[1] - height * size[0]) > ASPECT_TOLERANCE * width * size[1]:
                raise TruthError(
                    f"ground-truth {what} in {self.source} are {width}x{height}, "
                    f"the input is {size[0]}x{size[1]}: not the same scene"
                )

    def boxes_at(
        self, frame: int, min_area: float = 1.0, size: tuple[int, int] | None = None
    ) -> list[Box]:
        """True boxes of a frame; from a label mask, its connected moving regions, in
        pixels of an input of ``size`` (width, height) when the labels are at another scale."""
        if frame in self.boxes:
            return self.boxes[frame]
        mask = self.mask(frame)
        if mask is None:
            return []
        if size is not None and (mask.shape[1], mask.shape[0]) != size:
            mask = cv2.resize(mask, size, interpolation=cv2.INTER_NEAREST)
        return boxes_from_mask(mask == 255, min_area)


def boxes_from_mask(moving: np.ndarray, min_area: float) -> list[Box]:
    count, _, stats, _ = cv2.connectedComponentsWithStats(moving.astype(np.uint8), connectivity=8)
    return [
        Box(int(x), int(y), int(w), int(h))
        for x, y, w, h, area in stats[1:count]
        if area >= min_area
    ]


def load_truth(path: Path, input_frame_numbers: Sequence[int | None] | None = None) -> Truth:
    """Read ground truth from ``path``; ``input_frame_numbers`` are the numbers in
    the input's own frame names (None for a video file)."""
    if not path.exists():
        raise TruthError(f"ground truth not found: {path}")
    if path.is_dir():
        return _load_mask_folder(path, input_frame_numbers)
    if path.suffix.lower() == ".json":
        return _load_box_json(path)
    if path.suffix.lower() in MASK_SUFFIXES:
        return _load_masks([path], None, None, input_frame_numbers, str(path))
    raise TruthError(f"unknown ground-truth format: {path} (a CDnet folder, a mask image or JSON)")


def _load_mask_folder(folder: Path, input_numbers: Sequence[int | None] | None) -> Truth:
    sequence = folder.parent if folder.name == "groundtruth" else folder
    gt_folder = sequence / "groundtruth" if (sequence / "groundtruth").is_dir() else folder
    files = sorted(p for p in gt_folder.iterdir() if p.suffix.lower() in MASK_SUFFIXES)
    if not files:
        raise TruthError(f"no ground-truth images in {gt_folder}")
    temporal = _temporal_roi(sequence / "temporalROI.txt")
    roi = None
    for name in ("ROI.bmp", "ROI.png", "ROI.jpg"):
        if (sequence / name).is_file():
            roi_image = cv2.imread(str(sequence / name), cv2.IMREAD_GRAYSCALE)
            if roi_image is not None:
                roi = np.where(roi_image > 127, np.uint8(255), np.uint8(0))
                break
    return _load_masks(files, temporal, roi, input_numbers, str(folder))


def _load_masks(
    files: list[Path],
    temporal: tuple[int, int] | None,
    roi: Mask | None,
    input_numbers: Sequence[int | None] | None,
    source: str,
) -> Truth:
    numbered = {frame_number(p): p for p in files}
    truth = Truth(kind="masks", roi=roi, source=source)
    by_number = input_numbers is not None and all(n is not None for n in input_numbers)
    if by_number:
        assert input_numbers is not None
        index_of = {n: i for i, n in enumerate(input_numbers)}
        for number, p in numbered.items():
            if number in index_of and _inside(number, temporal):
                truth.mask_paths[index_of[number]] = p
    elif len(files) == 1 and None not in numbered:
        number = frame_number(files[0])
        assert number is not None
        truth.mask_paths[number] = files[0]
    else:
        for i, p in enumerate(files):
            if _inside(frame_number(p), temporal):
                truth.mask_paths[i] = p
    if not truth.mask_paths:
        raise TruthError(f"no ground-truth frame in {source} matches a frame of the input")
    return truth


def _inside(number: int | None, temporal: tuple[int, int] | None) -> bool:
    return temporal is None or number is None or temporal[0] <= number <= temporal[1]


def _temporal_roi(path: Path) -> tuple[int, int] | None:
    if not path.is_file():
        return None
    try:
        parts = path.read_text().split()
        return int(parts[0]), int(parts[1])
    except (OSError, IndexError, ValueError):  # ValueError covers text that is not UTF-8.
        raise TruthError(f"{path} should hold two frame numbers") from None


def _load_box_json(path: Path) -> Truth:
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise TruthError(f"cannot read {path}: {exc}") from None
    frames = data.get("frames") if isinstance(data, dict) else None
    if isinstance(frames, dict):
        items = [(key, value) for key, value in frames.items()]
    elif isinstance(frames, list):
        items = [
            (entry.get("frame"), entry.get("boxes")) if isinstance(entry, dict) else (None, None)
            for entry in frames
        ]
    else:
        raise TruthError(f'{path}: expected {{"frames": ...}} with boxes per frame')
    truth = Truth(kind="boxes", source=str(path))
    for key, boxes in items:
        try:
            frame = int(key)
        except (TypeError, ValueError):
            raise TruthError(f"{path}: frame {key!r} is not a frame number") from None
        if frame < 0:
            raise TruthError(f"{path}: frame {key!r} is below 0 (frames count from 0)")
        if not isinstance(boxes, list):
            raise TruthError(f"{path}: frame {key!r} needs a list of boxes")
        truth.boxes[frame] = [_box(b, path, frame) for b in boxes]
    return truth


def _box(value: object, path: Path, frame: int) -> Box:
    try:
        if isinstance(value, dict):
            x, y, w, h = (value[k] for k in ("x", "y", "w", "h"))
        elif isinstance(value, list | tuple) and len(value) == 4:
            x, y, w, h = value
        else:
            raise TypeError
        box = Box(int(x), int(y), int(w), int(h))
    except (KeyError, TypeError, ValueError, OverflowError):
        raise TruthError(
            f"{path}: frame {frame}: a box is [x, y, w, h] or {{x, y, w, h}}"
        ) from None
    if box.w <= 0 or box.h <= 0:
        raise TruthError(f"{path}: frame {frame}: box {box.as_list()} has no area")
    return box
