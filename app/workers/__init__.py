"""Workers: a thread per camera, a process per uploaded video, and the message bus."""

from app.workers.analysis import AnalysisManager
from app.workers.bus import EventBus
from app.workers.camera import CameraWorker
from app.workers.manager import CameraManager

__all__ = ["AnalysisManager", "CameraManager", "CameraWorker", "EventBus"]
