"""The pre-roll: an activated camera's last seconds of frames, kept as the camera gave them."""

from __future__ import annotations

from collections import deque

from app.recording.mp4 import ClipFrame


class PreRoll:
    """The frames of the last ``seconds`` (by their monotonic times), and the one before
    them, which was showing ``seconds`` ago; at most ``max_bytes`` of them: past either,
    the oldest go. A JPEG camera's frames are its own JPEGs (about 40 KB at 640x480: 3 s
    at 25 fps hold 3 MB), referenced, not copied; a decoded camera's are I420 (460 KB at
    640x480), so ``max_bytes`` shortens its pre-roll at large sizes rather than let it
    take the memory."""

    def __init__(self, seconds: float, max_bytes: int) -> None:
        self.seconds = seconds
        self.max_bytes = max_bytes
        self._frames: deque[ClipFrame] = deque()
        self.nbytes = 0

    def __len__(self) -> int:
        return len(self._frames)

    def add(self, frame: ClipFrame) -> None:
        self._frames.append(frame)
        self.nbytes += frame.nbytes
        oldest = frame.mono - self.seconds
        frames = self._frames
        while len(frames) > 1 and frames[1].mono <= oldest:  # The next was showing by then.
            self.nbytes -= frames.popleft().nbytes
        while frames and self.nbytes > self.max_bytes:
            self.nbytes -= frames.popleft().nbytes

    def since(self, moment: float) -> list[ClipFrame]:
        """The frames from the one showing at ``moment`` (the last that came by then, or
        the oldest held if none had) to the newest."""
        frames = list(self._frames)
        first = 0
        for index, frame in enumerate(frames):
            if frame.mono > moment:
                break
            first = index
        return frames[first:]

    def clear(self) -> None:
        self._frames.clear()
        self.nbytes = 0
