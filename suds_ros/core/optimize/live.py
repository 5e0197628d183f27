"""The gait search on a live stream: stamped samples in, gait commands out.

:class:`LiveGaitSearch` drives a :class:`~suds_ros.core.optimize.loop.GaitSearch` from shape and
pose samples as they arrive (the ``optimizer`` node is its thin adapter).  It never sees the
physics, and it places everything by **stamps**, never by arrival:

1. A gait is commanded (:meth:`LiveGaitSearch.command`).  The robot switches at its next cycle
   boundary and says so with the stamp of the first sample of the new gait (the simulator node's
   ``suds/gait_switch``): :meth:`LiveGaitSearch.on_switch` with that stamp *t_s* opens the
   measured window [*t_s* + settle/f, *t_s* + (settle + measured)/f]: the settling cycles (the fade
   onto the new gait and the passive transient) are skipped.  A robot that cannot say when it
   switched gets :meth:`LiveGaitSearch.assume_switch`: *t_s* = the newest shape stamp at the
   command + 1/f (its next cycle boundary at the latest, if the command reached it at once).
2. Samples are kept from the command on (in any arrival order; sorted and de-duplicated by
   stamp when taken), so a switch message that arrives late loses nothing.  The window is
   complete when both streams have a sample at or past its end.
3. The window's samples become a :class:`~suds_ros.core.recording.Recording` (pose yaw
   unwrapped) for :func:`decide`: :meth:`GaitSearch.observe`, then :meth:`GaitSearch.request`
   (the fit and the step: the slow part, which the node runs in another process).

Cycle accounting: the search counts the cycles it asked for; the robot ran more (the wait for a
cycle boundary and the time spent deciding), which :attr:`LiveGaitSearch.cycles_elapsed` counts
from the stamps, first sample to newest.  Both are reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from suds_ros.core.errors import SudsDataError
from suds_ros.core.optimize.loop import GaitSearch, LoopIteration, RunRequest
from suds_ros.core.physics.gait import Gait, same_gait
from suds_ros.core.recording import Recording

TOO_FEW_SAMPLES = "too_few_samples"


@dataclass(frozen=True)
class Window:
    """The measured stretch of a commanded run, by stamps (s)."""

    request: RunRequest
    switched: float
    start: float
    end: float


def decide(search: GaitSearch, data: Recording) -> tuple[GaitSearch, LoopIteration, RunRequest | None]:
    """Observe a window's recording and ask for the next run; returns the search (for another process)."""
    it = search.observe(data)
    return search, it, search.request()


class LiveGaitSearch:
    """Collect the stamped samples of each commanded run for a :class:`GaitSearch` (module docstring).

    Parameters
    ----------
    search : GaitSearch
    joint_names, actuated, passive : sequence of str
        The robot's joints in recording order, and their roles.
    system : str
        The robot's name (for the recordings handed to the search).
    """

    def __init__(self, search: GaitSearch, joint_names: tuple[str, ...], actuated: tuple[str, ...],
                 passive: tuple[str, ...], system: str) -> None:
        self.search = search
        self.joint_names, self.actuated, self.passive, self.system = joint_names, actuated, passive, system
        self.commanded: RunRequest | None = None
        self.commanded_at = -math.inf
        self.window: Window | None = None
        self.first_stamp: float | None = None
        self.newest_shape = -math.inf
        self.newest_pose = -math.inf
        self._shape: dict[float, np.ndarray] = {}
        self._effort: dict[float, np.ndarray] = {}
        self._pose: dict[float, tuple[float, float, float]] = {}

    # ------------------------------------------------------------ samples
    def on_shape(self, stamp: float, r: np.ndarray, effort: np.ndarray | None = None) -> None:
        """A shape sample: joint values in ``joint_names`` order (finite; checked by the caller).

        ``effort``: the joints' efforts over the sample period, if the robot reports them (needed for
        the ``efficiency`` objective).
        """
        if self.first_stamp is None:
            self.first_stamp = stamp
        self.newest_shape = max(self.newest_shape, stamp)
        if self.commanded is not None and stamp > self.commanded_at:
            self._shape[stamp] = np.asarray(r, dtype=float)
            if effort is not None:
                self._effort[stamp] = np.asarray(effort, dtype=float)

    def on_pose(self, stamp: float, x: float, y: float, yaw: float) -> None:
        """A pose sample of the body frame (m, m, rad)."""
        self.newest_pose = max(self.newest_pose, stamp)
        if self.commanded is not None and stamp > self.commanded_at:
            self._pose[stamp] = (x, y, yaw)

    @property
    def cycles_elapsed(self) -> float:
        """Cycles the robot has run since the first shape sample (from the stamps)."""
        if self.first_stamp is None:
            return 0.0
        return (self.newest_shape - self.first_stamp) * self.search.best.gait_hz

    # ------------------------------------------------------------ commands
    def command(self, request: RunRequest) -> None:
        """``request``'s gait is being commanded now: keep the samples from here on, wait for its switch."""
        self.commanded = request
        self.commanded_at = self.newest_shape
        self.window = None
        self._shape.clear()
        self._effort.clear()
        self._pose.clear()

    def on_switch(self, stamp: float, gait: Gait) -> Window | None:
        """The robot runs ``gait`` from the sample stamped ``stamp``: open the window if it is the commanded one."""
        req = self.commanded
        if req is None or self.window is not None or not stamp > self.commanded_at or not same_gait(gait, req.gait):
            return None  # not ours: another command's, or an older switch to the same gait
        return self._open(stamp)

    def assume_switch(self) -> Window:
        """For a robot that does not report its switches: assume it at the next cycle boundary after the command."""
        req = self.commanded
        assert req is not None
        t = self.commanded_at if math.isfinite(self.commanded_at) else 0.0
        return self._open(t + 1.0 / req.gait.gait_hz)

    def _open(self, stamp: float) -> Window:
        req = self.commanded
        assert req is not None
        f = req.gait.gait_hz
        settle = self.search.config.settle_cycles
        start = stamp + settle / f
        self.window = Window(request=req, switched=stamp, start=start,
                             end=start + (req.cycles - settle) / f)
        return self.window

    def complete(self) -> bool:
        """True when both streams have reached the end of the open window."""
        w = self.window
        return w is not None and self.newest_shape >= w.end and self.newest_pose >= w.end

    def take(self) -> Recording:
        """The open window's samples as a recording; the command and window are closed.

        Raises
        ------
        SudsDataError
            Fewer than 8 shape or pose samples in the window (code ``too_few_samples``): a stream
            stalled or lost most of its samples.
        """
        w = self.window
        assert w is not None
        ts = np.array(sorted(t for t in self._shape if w.start <= t <= w.end), dtype=float)
        ps = np.array(sorted(t for t in self._pose if w.start <= t <= w.end), dtype=float)
        r = np.stack([self._shape[t] for t in ts]) if ts.size else np.zeros((0, len(self.joint_names)))
        effort = np.stack([self._effort[t] for t in ts]) if ts.size and all(t in self._effort for t in ts) else None
        pose = np.array([self._pose[t] for t in ps], dtype=float).reshape(-1, 3)
        self.commanded, self.window = None, None
        self._shape.clear()
        self._effort.clear()
        self._pose.clear()
        need = 8
        if ts.size < need or ps.size < need:
            raise SudsDataError(f"window [{w.start:.3f}, {w.end:.3f}] s: expected at least {need} shape and pose "
                                f"samples, got {ts.size} and {ps.size}", code=TOO_FEW_SAMPLES)
        pose[:, 2] = np.unwrap(pose[:, 2])
        return Recording(t=ts, r=r, joint_names=self.joint_names, actuated=self.actuated, passive=self.passive,
                         pose_t=ps, pose=pose, system=self.system, gait_hz=w.request.gait.gait_hz, effort=effort)
