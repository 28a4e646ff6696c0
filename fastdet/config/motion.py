"""What counts as moving for the oncoming-traffic model in video (:class:`MotionGate`)."""
from __future__ import annotations

from dataclasses import dataclass

from ._base import Config


@dataclass(frozen=True)
class MotionGate(Config):
    """What counts as moving for the oncoming-traffic (wide-window) model in video.

    Oncoming cars cross the view several times faster than the scenery beside them, so a
    wide window only counts when the picture inside it changed since the frame
    ``1 / reference_fps`` seconds earlier: the mean absolute difference of the grey levels
    (0..255, ``cv2.COLOR_BGR2GRAY``) of the two frames over the window's pixels must reach
    the gate, ``max(min_motion, noise_factor x noise)`` where ``noise`` is the median
    absolute difference over the whole region the oncoming search covers (what the picture
    moves, or its noise, everywhere). The oncoming search itself only runs over the columns
    of each band that hold such a window. How the defaults were measured:
    docs/accuracy.md.

    Frame rate (:meth:`lag`): at ``fps`` frames per second the frame compared with is
    ``round(fps / reference_fps)`` frames back (at least 1), so a 50 fps video (or one
    whose frames are doubled) is judged on the same 40 ms of motion as the 25 fps footage
    the thresholds were measured on. Below ``reference_fps`` the previous frame is used
    (the motion of a car grows less than in proportion to the time between frames).

    min_motion: grey levels; ``0`` turns the gate (and the narrowing) off.
    noise_factor: the gate is at least this many times the region's median motion (``0``:
        an absolute gate, the default).
    reference_fps: frames per second the thresholds are for.
    """

    min_motion: float = 45.0
    noise_factor: float = 0.0
    reference_fps: float = 25.0

    def __post_init__(self) -> None:
        if not 0 <= self.min_motion < 256:
            raise ValueError(f"min_motion must be in [0, 256), got {self.min_motion!r}")
        if not 0 <= self.noise_factor < 256:
            raise ValueError(f"noise_factor must be in [0, 256), got {self.noise_factor!r}")
        if not 0 < self.reference_fps < 1000:
            raise ValueError(f"reference_fps must be in (0, 1000), got {self.reference_fps!r}")

    def lag(self, fps: float | None) -> int:
        """Frames between the two frames compared at ``fps`` (``None``: the reference rate)."""
        if fps is None or not fps > 0:
            return 1
        return max(1, round(fps / self.reference_fps))

    def threshold(self, noise: float) -> float:
        """The gate for a region whose median motion is ``noise`` grey levels."""
        return max(self.min_motion, self.noise_factor * noise) if self.min_motion > 0 else 0.0
