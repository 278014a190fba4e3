"""The adaptive method's settings: its rates, the counts of frames that stand for
times, and a switch per mechanism, so that each can be turned off, measured and tested
alone (``bench/scenes.py --off NAME``). Every default is what Vigil ships."""

from __future__ import annotations

from dataclasses import dataclass, fields


@dataclass(frozen=True)
class AdaptiveConfig:
    k: float = 3.5
    """Thresholds per unit of deviation: 3.5 sigma of camera noise, not the usual 4: the
    per-pixel variability, not a higher global threshold, is what keeps swaying pixels
    quiet."""
    learning_rate: float = 0.03
    """How fast a still pixel's mode follows the frame."""
    light_switch_fraction: float = 0.5
    """The share of the view (and of what was still) a light switch changes."""
    mode_rate: float = 0.04
    """How fast the alternate's weight follows its recurrences. A new alternate seen right
    after a background frame starts at this, below ``mode_weight``, so it takes a second
    sighting to count: with the defaults, within 17 frames."""
    mode_weight: float = 0.06
    """The weight (0..1) at which the alternate counts as background."""
    deviation_rate: float = 0.1
    """How fast a pixel's variability follows its deviation, once the scene is learned."""
    weak_fraction: float = 0.5
    """Of a pixel's own threshold: what counts as moving next to a strong pixel."""
    absorb_after: int = 125
    """Frames (at 25 fps) an object that stopped is kept: 5 s."""
    relit_after: int = 30
    """Frames (at 25 fps) after which a still region that is no object is absorbed."""
    check_every: int = 6
    """Frames (at 25 fps) between still-region checks."""
    learning_frames: int = 20
    """Frames over which the scene is learned first (counted as frames, at any rate)."""
    settle_frames: int = 10
    """Frames (at 25 fps, at most 255) a neighbour must have been still for the ghost step
    to take it near something that stirs."""

    # The mechanisms (see each module's docstring), all on by default.
    selective_update: bool = True
    """Only still pixels teach their mode (``learning``)."""
    second_mode: bool = True
    """An alternate mode counts as background once it recurs (``learning``)."""
    variability: bool = True
    """Each pixel's own threshold from its variability (``threshold``, ``learning``)."""
    near_motion_teaching: bool = True
    """Still pixels next to motion teach the variability slowly (``learning``)."""
    learning_phase: bool = True
    """The first ``learning_frames`` frames learn the scene by their own rules."""
    hysteresis: bool = True
    """Weak pixels next to strong ones count (``threshold``)."""
    frame_gain: bool = True
    """The background lit by the frame's brightness ratio (``gains``)."""
    row_gains: bool = True
    """Rows lit by their own ratio under bands of mains light (``gains``)."""
    light_switch: bool = True
    """A change of light over the whole view is re-learned, not reported (``light``)."""
    relight_objects: bool = True
    """What was moving at a light switch keeps its old background, relit (``light``)."""
    follow_view: bool = True
    """A knocked, shaking or turning camera is followed (``view``)."""
    ghost_absorption: bool = True
    """What was in the first frame and left is eaten from its rim (``ghosts``)."""
    stirring_guard: bool = True
    """Near what stirs, only settled neighbours feed the ghost step (``ghosts``)."""
    still_regions: bool = True
    """Regions that stay "moving" without a change become background (``regions``)."""
    keep_stopped: bool = True
    """An object that stopped is kept whole, out of the ghost step's reach (``regions``)."""
    keep_plain_movers: bool = True
    """A region moving with an unchanging inside is kept whole (``regions``)."""
    start_from_scene: bool = True
    """Start from a scene estimated ahead where one is given (``seed``)."""

    def __post_init__(self) -> None:
        if not 0 <= self.settle_frames <= 255:
            raise ValueError(f"settle_frames counts to 255 at most, not {self.settle_frames}")


MECHANISMS = tuple(field.name for field in fields(AdaptiveConfig) if field.type == "bool")
"""The names of the switches, in the order of the config."""
