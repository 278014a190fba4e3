"""Damage real MJPEG AVIs the way a bad disk or a cut download does."""

from __future__ import annotations

from pathlib import Path


def jpeg_chunks(data: bytes) -> list[tuple[int, int]]:
    """(offset, size) of each frame's JPEG in an MJPEG AVI, in order."""
    chunks = []
    at = 0
    while (at := data.find(b"00dc", at)) >= 0:
        size = int.from_bytes(data[at + 4 : at + 8], "little")
        if data[at + 8 : at + 10] == b"\xff\xd8":
            chunks.append((at + 8, size))
            at += 8 + size
        else:
            at += 4
    return chunks


def garble_frames(video: Path, frames: list[int], out: Path) -> Path:
    """A copy of ``video`` whose JPEGs of ``frames`` (0-based) are garbage of the same size."""
    data = bytearray(video.read_bytes())
    chunks = jpeg_chunks(bytes(data))
    for frame in frames:
        offset, size = chunks[frame]
        data[offset : offset + size] = b"A" * size
    out.write_bytes(bytes(data))
    return out


def cut_after(video: Path, frames: int, out: Path) -> Path:
    """A copy of ``video`` cut inside frame ``frames``' JPEG: the header still claims all."""
    data = video.read_bytes()
    offset, size = jpeg_chunks(data)[frames]
    out.write_bytes(data[: offset + size // 2])
    return out
