"""Vigil's default motion method, one mechanism per module (``method`` for the tour)."""

from app.vision.motion.adaptive.config import MECHANISMS, AdaptiveConfig
from app.vision.motion.adaptive.light import relit
from app.vision.motion.adaptive.method import AdaptiveBackground, warm_up

__all__ = ["MECHANISMS", "AdaptiveBackground", "AdaptiveConfig", "relit", "warm_up"]
