"""Watching a run frame by frame from outside the method: what `run_frames` calls, if given one.

An observer sees each frame and the pose the method returned for it, and may read the method's
public state (a `graph` attribute, say); it must not change either. Its time is measured apart
from the method's, so the method's own figures stay the same whether it watches or not. Like a
method, it may set `images_every_frame` (e.g. ("rgb", "depth")): the engine then decodes those
ahead on its second thread (run/read_ahead.py) instead of the observer waiting for them.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from longslam.core.frame import Frame
from longslam.slam.api import MethodContext, Result


class RunObserver(Protocol):
    def start(self, method: Any, context: MethodContext) -> None:
        """Before the first frame."""
        ...

    def frame(self, frame: Frame, pose: np.ndarray, method: Any) -> None:
        """After the method's `step` returned `pose` for `frame`."""
        ...

    def finish(self, result: Result) -> None:
        """After the method's `finish`."""
        ...
