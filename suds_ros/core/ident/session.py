"""A live identification session: what the estimator node does, without ROS.

The node converts messages and hands them here; this module decides what to do
with them and reports what to publish.

* **Joint roles**: from the ``actuated`` parameter (joint names from the first
  shape sample), else the ``system`` parameter (the caller looks the system up
  and calls :meth:`EstimatorSession.start`), else the system description the
  node receives (:meth:`EstimatorSession.on_system`), else a resumed
  checkpoint's.  Samples that arrive before the roles are known wait.
* **Pairing** (by stamps only, never by arrival time) is the estimator's
  (:mod:`~suds_ros.core.ident.pairing`): a shape sample waits until a pose
  with a stamp at or after its own arrives, or is dropped once the shape stream
  has run ``max_pose_wait`` stamp seconds past it.  So a late, slow or bursty
  delivery of either stream (a restarted node catching up on history) never
  loses a pairable sample, as long as one stream runs less than
  ``max_pose_wait`` ahead of the other.  The status warns once the shape
  stream has run ``pose_stall`` seconds ahead of the pose stream.  Before the
  joint roles are known, samples wait here (at most ``history_depth``).
* **Resume**: with a ``checkpoint`` file the estimator is restored from it
  (through the checkpoint I/O the caller hands in, :mod:`suds_ros.io.checkpoint`);
  samples at or before its last stamps are counted as ``replayed`` and skipped.
  A checkpoint that cannot be used (damaged, foreign, another version, other
  joints) is moved aside to ``<checkpoint>.refused-<n>``, the reason logged as
  an error, and the estimator starts afresh: nothing is overwritten.
* **Bad samples** (NaN, duplicate or out-of-order stamp, wrong joint names or
  count, ...) are checked once, by the estimator, skipped, logged once per
  reason and counted per ``<stream>.<error code>``; the session never stops on
  traffic.
* **Cadence** (wall clock, given as ``now``): the model is published after each
  fitted chunk (``model_period`` = 0) or every ``model_period`` s, and once no
  sample has arrived for ``idle_flush`` s (the partial chunk); the status every
  ``status_period`` s; the checkpoint every ``checkpoint_period`` s.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, NamedTuple, Protocol

from suds_ros.core.config import check_settings, setting
from suds_ros.core.errors import (
    QUEUE_FULL,
    SudsConfigError,
    SudsDataError,
    SudsError,
    SudsPhaseError,
    error_code,
)
from suds_ros.core.ident.model import SudsModel, check_stamp
from suds_ros.core.ident.online import OnlineConfig, OnlineSudsEstimator

Log = Callable[[str, str], None]  # (level "info" | "warning" | "error", text)


class CheckpointIO(Protocol):
    """Reads and writes estimator checkpoints (:mod:`suds_ros.io.checkpoint` is one)."""

    def load_estimator(self, path: str) -> OnlineSudsEstimator:
        """The estimator saved in ``path``; SudsError when it cannot be used."""

    def save_estimator(self, path: str, est: OnlineSudsEstimator) -> None:
        """Write ``est`` to ``path`` atomically."""


def _gamma_value(g: float | None) -> str:
    """A running Γ as a status value: 4 decimals ("nan" before two chunks), "none" where it does not apply."""
    return "none" if g is None else f"{g:.4f}"


def _no_log(level: str, text: str) -> None:
    pass


@dataclass(frozen=True)
class SessionConfig:
    """Parameters of a session (the estimator node's parameters; periods and ``pose_stall`` may change).

    ``online`` holds the estimator's own settings (:class:`OnlineConfig`, with its
    :class:`~suds_ros.core.ident.sysid.SudsConfig`); the node names their parameters by the bare
    field names (``chunk``, ``linear_order``, ``ridge``, ...), its ``gait_hz`` is this config's.
    """

    online: OnlineConfig = setting(
        default_factory=OnlineConfig, description="the streaming estimator's settings",
        parameters={"flatten": True, "exclude": ("gait_hz", "alternatives")})
    system: str = setting("", "system id giving the joint roles (empty: `actuated`, else /suds/system)")
    actuated: tuple[str, ...] = setting((), "actuated joint names (empty: from `system` or /suds/system)")
    gait_hz: float = setting(0.0, "nominal gait frequency, Hz (0: from /suds/system, else 1)", ge=0.0, le=1000.0)
    history_depth: int = setting(6000, "subscription depth of shape/pose and the most shape samples waiting "
                                       "for the joint roles",
                                 ge=1, le=10_000_000)
    checkpoint: str = setting("", "checkpoint file: resumed from at start if it exists (empty: none)")
    checkpoint_period: float = setting(5.0, "wall s between checkpoints", ge=0.01, le=86400.0, read_only=False)
    model_period: float = setting(0.0, "wall s between /suds/model updates (0: after each fitted chunk)",
                                  ge=0.0, le=86400.0, read_only=False)
    status_period: float = setting(1.0, "wall s between /suds/status messages", ge=0.05, le=3600.0,
                                   read_only=False)
    pose_stall: float = setting(
        60.0, "stamp s the shape stream may run ahead of the pose stream before the status warns that the "
              "pose stream stalled (waiting shape samples are dropped after `max_pose_wait`)",
        ge=0.01, le=3600.0, read_only=False)
    idle_flush: float = setting(2.0, "wall s without samples before the partial chunk is fitted and published",
                                ge=0.01, le=3600.0, read_only=False)

    def __post_init__(self) -> None:
        check_settings(self)
        if self.system and self.actuated:
            raise SudsConfigError("`system` and `actuated`: give one of them, not both")

    def online_config(self, gait_hz: float) -> OnlineConfig:
        """The :class:`OnlineConfig` these parameters describe, at the gait frequency ``gait_hz``."""
        return replace(self.online, gait_hz=gait_hz)


class Status(NamedTuple):
    """What /suds/status reports: level ``OK``/``WARN``/``ERROR``, a message and key/values."""

    level: str
    message: str
    values: dict[str, str]


class EstimatorSession:
    """Pairing, roles, resume, cadence and status around an :class:`OnlineSudsEstimator`.

    Parameters
    ----------
    config : SessionConfig
    log : callable (level, text), optional
        Where log lines go (the node's logger).
    now : float
        Wall time of the start, s.
    checkpoints : CheckpointIO, optional
        Needed with a ``checkpoint`` file.

    Raises
    ------
    SudsConfigError
        A ``checkpoint`` without ``checkpoints``, or ``system`` is unknown.
    """

    def __init__(self, config: SessionConfig, log: Log = _no_log, now: float = 0.0,
                 checkpoints: CheckpointIO | None = None) -> None:
        if config.checkpoint and checkpoints is None:
            raise SudsConfigError("`checkpoints`: a `checkpoint` file needs checkpoint I/O, got None")
        self.config = config
        self._log = log
        self.est: OnlineSudsEstimator | None = None
        self.skipped: Counter[str] = Counter()
        self.replayed = self.replayed_pose = self.model_updates = 0
        self.error = ""
        self.resumed_from = ""
        self.refused_checkpoint = ""
        self._io = checkpoints
        self._resume = (-math.inf, -math.inf)  # last shape / pose stamps of a resumed checkpoint
        self._gait_from = -math.inf  # samples before this stamp belong to a gait left (new_gait)
        self.gait_settling = 0  # samples skipped for it
        self.gaits = 1
        self._shapes: deque[Any] = deque()  # shape samples waiting for the joint roles, in stamp order
        self._poses: deque[Any] = deque(maxlen=config.history_depth)  # before the roles are known
        self._newest_shape = -math.inf  # newest shape stamp accepted in this session
        self._first_shape = math.inf  # first shape stamp accepted in this session
        self._last_arrival: float | None = None
        self._stall_logged = False
        self._dirty = False
        self._rows_published = -1
        self._last_status = self._last_ckpt = self._last_model = now
        self._saved_at = (-1, -1, -1)
        if config.checkpoint and Path(config.checkpoint).exists():
            self._load(config.checkpoint)

    # ------------------------------------------------------------ roles and resume
    @property
    def needs_system(self) -> bool:
        """True while the joint roles can only come from a system description."""
        return self.est is None and not self.config.actuated

    def _load(self, path: str) -> None:
        try:
            est = self._io.load_estimator(path)  # type: ignore[union-attr]
            if self.config.actuated and tuple(self.config.actuated) != est.actuated:
                raise SudsConfigError(f"`actuated`: {list(self.config.actuated)} differs from the checkpoint's "
                                      f"{list(est.actuated)}")
        except SudsError as exc:
            self._refuse_checkpoint(path, exc)
            return
        self.est = est
        self._resume = (est.last_shape_stamp, est.last_pose_stamp)
        self._newest_shape = est.last_shape_stamp
        self.resumed_from = path
        self._dirty = True
        self._log("info", f"resumed from checkpoint {path}: {est.n_shape} shape samples, "
                          f"{est.cycles_seen:.2f} cycles, last stamp {est.last_shape_stamp:.6f} s")

    def _refuse_checkpoint(self, path: str, exc: SudsError) -> None:
        """Move an unusable checkpoint aside (never overwritten) and say so."""
        n = 1
        while Path(f"{path}.refused-{n}").exists():
            n += 1
        aside = f"{path}.refused-{n}"
        try:
            Path(path).rename(aside)
        except OSError as err:
            raise SudsConfigError(f"`checkpoint`: {path} cannot be used ({exc}) nor moved aside ({err}); "
                                  "move or remove it") from None
        self.refused_checkpoint = aside
        self._log("error", f"checkpoint {path} refused [{exc.code}]: {exc}; moved to {aside}, starting afresh")

    def start(self, names: tuple[str, ...], actuated: tuple[str, ...], gait_hz: float, source: str) -> None:
        """Create the estimator (once) and hand it the samples that waited for the roles."""
        if self.est is not None:
            return
        self.est = OnlineSudsEstimator(names, actuated, self.config.online_config(gait_hz))
        self._log("info", f"joints {list(names)}, actuated {list(actuated)} (from {source}), gait {gait_hz:g} Hz")
        poses, self._poses = list(self._poses), deque(maxlen=self.config.history_depth)
        for p in poses:
            self._feed_pose(p)
        shapes, self._shapes = list(self._shapes), deque()
        for s in shapes:  # checked against the joints now
            self._feed_shape(s)

    def new_gait(self, gait_hz: float, switched: float) -> bool:
        """The robot runs another gait from the sample stamped ``switched``: start the estimator afresh.

        The gait template and the SUDS model are local to one gait, so nothing of the old gait's
        fit is kept: a fresh estimator (same joints and roles, ``gait_hz``) takes the samples
        stamped one cycle after the switch on (the new gait fades in over that cycle); earlier ones
        are skipped (counted in ``gait_settling``).  Returns False (nothing done) before the roles
        are known or when no sample before the switch was taken (the stream began with that gait).
        """
        est = self.est
        if est is None or not self._first_shape < switched:
            return False
        self.gaits += 1
        self.est = OnlineSudsEstimator(est.joint_names, est.actuated, self.config.online_config(gait_hz))
        self._gait_from = switched + 1.0 / gait_hz
        self._rows_published = -1
        self._log("info", f"new gait ({gait_hz:g} Hz) from stamp {switched:.3f}: the model is local to a gait, so "
                          f"the estimator starts afresh from stamp {self._gait_from:.3f} (phase, template and "
                          "model re-learned)")
        return True

    def on_system(self, info: Mapping[str, Any]) -> None:
        """A system description (``joint_names``, ``actuated``, ``gait_hz``, ``system``) gives the roles."""
        if self.est is not None:
            return
        self.start(tuple(info["joint_names"]), tuple(info["actuated"]),
                   self.config.gait_hz or info.get("gait_hz") or 1.0, f"system description ({info.get('system')})")

    # ------------------------------------------------------------ traffic
    def skip(self, stream: str, exc: BaseException) -> None:
        """Count a rejected ``stream`` sample under ``<stream>.<code>``; log the first of each reason."""
        key = f"{stream}.{error_code(exc)}"
        if not self.skipped[key]:
            self._log("warning", f"skipping bad {stream} sample(s) [{key}]: {exc} "
                                 "(logged once per reason; counted in /suds/status)")
        self.skipped[key] += 1

    def on_shape(self, sample: Any, now: float) -> SudsModel | None:
        """A shape sample (``stamp``, ``names``, ``position``); returns a model to publish, if any."""
        self._last_arrival = now
        if sample.stamp <= self._resume[0]:
            self.replayed += 1  # already in the resumed checkpoint
            return None
        if sample.stamp < self._gait_from:
            self.gait_settling += 1  # the switch to a new gait and its fade
            return None
        if self.est is None and self.config.actuated and set(self.config.actuated) <= set(sample.names):
            self.start(tuple(sample.names), tuple(self.config.actuated), self.config.gait_hz or 1.0,
                       "`actuated` and the first shape message")
        if self.est is not None:
            self._feed_shape(sample)
            return self._model_if_fitted(now)
        try:  # waits for the joint roles: only the stamp order can be checked yet
            check_stamp("shape", sample.stamp, self._newest_shape)
        except SudsError as exc:
            self.skip("shape", exc)
            return None
        if len(self._shapes) >= self.config.history_depth:
            self.skip("shape", SudsDataError(f"shape queue: {len(self._shapes)} samples already wait for the "
                                             "joint roles", code=QUEUE_FULL))
            return None
        self._newest_shape = sample.stamp
        self._first_shape = min(self._first_shape, sample.stamp)
        self._shapes.append(sample)
        return None

    def on_pose(self, pose: Any, now: float) -> SudsModel | None:
        """A planar pose (``stamp``, ``x``, ``y``, ``yaw``); returns a model to publish, if any."""
        self._last_arrival = now
        if pose.stamp <= self._resume[1]:
            self.replayed_pose += 1
            return None
        if pose.stamp < self._gait_from:
            self.gait_settling += 1
            return None
        if self.est is None:
            self._poses.append(pose)
            return None
        self._feed_pose(pose)
        return self._model_if_fitted(now)

    def _feed_pose(self, pose: Any) -> None:
        self._feed("pose", self.est.add_pose, pose.stamp, pose.x, pose.y, pose.yaw)  # type: ignore[union-attr]

    def _feed_shape(self, s: Any) -> None:
        if self._feed("shape", self.est.add_shape, s.stamp, s.names, s.position):  # type: ignore[union-attr]
            self._newest_shape = s.stamp
            self._first_shape = min(self._first_shape, s.stamp)

    def _feed(self, stream: str, add: Any, *args: Any) -> bool:
        """Hand one sample to the estimator; a bad sample is skipped (counted by its code), never fatal."""
        try:
            add(*args)
        except SudsPhaseError as exc:
            self._phase_error(exc)
            return True  # the sample itself was accepted
        except Exception as exc:  # noqa: BLE001 - the session never stops on traffic
            self.skip(stream, exc)
            return False
        self._dirty = True
        return True

    def _drain(self) -> None:
        """Fit what the regridding holds for its successors (the stream paused or ended)."""
        if self.est is not None and self.est.held:
            self._feed("shape", self.est.drain)

    def _model_if_fitted(self, now: float) -> SudsModel | None:
        """The model to publish after each fitted chunk (``model_period`` 0)."""
        est = self.est
        if est is not None and self.config.model_period == 0 and est.n_rows != self._rows_published:
            return self._take_model(now)
        return None

    def _phase_error(self, exc: Exception) -> None:
        if not self.error:
            self._log("error", f"initialisation failed: {exc}")
        self.error = f"initialisation failed: {exc}"

    def _take_model(self, now: float | None = None) -> SudsModel | None:
        est = self.est
        if est is None or not est.initialised:
            return None
        try:
            model = est.model()
        except SudsError:
            return None
        self._rows_published = est.n_rows
        self._dirty = False
        self.model_updates += 1
        if now is not None:
            self._last_model = now
        return model

    # ------------------------------------------------------------ periodic
    def pose_stalled(self) -> float | None:
        """Stamp s the shape stream has run ahead of the pose stream, when more than ``pose_stall``."""
        if self._newest_shape == -math.inf:
            return None
        last_pose = self.est.last_pose_stamp if self.est is not None else max(
            (p.stamp for p in self._poses), default=-math.inf)
        ahead = self._newest_shape - max(last_pose, self._first_shape)
        return ahead if ahead > self.config.pose_stall else None

    def tick(self, now: float) -> tuple[SudsModel | None, Status | None]:
        """Periodic work at wall time ``now``: (model to publish or None, status to publish or None)."""
        cfg = self.config
        model = None
        idle = self._last_arrival is not None and now - self._last_arrival > cfg.idle_flush
        if idle:
            self._drain()
        if self._dirty and (idle or (cfg.model_period > 0 and now - self._last_model >= cfg.model_period)):
            model = self._take_model(now)
            if model is not None and idle:
                self._log("info", f"idle for {cfg.idle_flush:g} s: published the model ({model.n_samples} rows)")
        stalled = self.pose_stalled()
        if stalled is not None and not self._stall_logged:
            self._log("warning", f"pose stream stalled since {stalled:.1f} s")
        self._stall_logged = stalled is not None  # log once per stall
        status = None
        if now - self._last_status >= cfg.status_period:
            self._last_status = now
            status = self.status(stalled)
        if cfg.checkpoint and now - self._last_ckpt >= cfg.checkpoint_period:
            self._last_ckpt = now
            self.save_checkpoint()
        return model, status

    def status_values(self) -> dict[str, str]:
        """The key/values of the status."""
        est = self.est
        v: dict[str, str] = {}
        if est is not None:
            g = est.running_gamma()
            v.update({
                "phase": f"{est.phase:.6g}", "cycles_seen": f"{est.cycles_seen:.3f}",
                "initialised": str(est.initialised).lower(), "samples": str(est.n_shape),
                "poses": str(est.n_pose), "rows": str(est.n_rows),
                "gamma_body": _gamma_value(g["body"]), "gamma_passive": _gamma_value(g["passive"]),
                "dropped_no_pose": str(est.dropped_no_pose),
                "shape_grid": "off" if est.regrid is None else est.regrid.mode, "held_for_grid": str(est.held),
            })
            v.update({f"residual.{c}": f"{r:.6g}" for c, r in zip(est.channels, est.last_residual)})
        else:
            v.update({"initialised": "false", "samples": "0", "joint_roles": "unknown"})
        waiting = len(self._shapes) + (est.waiting_for_pose if est is not None else 0)
        v.update({"replayed": str(self.replayed), "replayed_pose": str(self.replayed_pose),
                  "waiting_for_pose": str(waiting), "model_updates": str(self.model_updates),
                  "skipped_total": str(sum(self.skipped.values()))})
        v.update({f"skipped.{k}": str(n) for k, n in sorted(self.skipped.items())})
        if self.resumed_from:
            v["resumed_from"] = self.resumed_from
        if self.refused_checkpoint:
            v["refused_checkpoint"] = self.refused_checkpoint
        return v

    def status(self, stalled: float | None = None) -> Status:
        """ERROR on a failed initialisation, WARN on a stalled pose stream, else OK."""
        level, message = "OK", "running"
        if self.est is None:
            message = "waiting for joint roles (`actuated`, `system` or /suds/system)"
        elif not self.est.initialised:
            message = f"initialising ({self.est.cycles_seen:.1f}/{self.est.init_cycles_:g} cycles)"
        if stalled is not None:
            level, message = "WARN", f"pose stream stalled since {stalled:.1f} s"
        if self.error:
            level, message = "ERROR", self.error
        return Status(level, message, self.status_values())

    def save_checkpoint(self) -> None:
        """Atomically save the estimator state (if it changed since the last save)."""
        est = self.est
        if est is None or not self.config.checkpoint:
            return
        mark = (est.n_shape, est.n_pose, est.held)  # a drain of the live grid changes the state too
        if mark == self._saved_at:
            return
        try:
            self._io.save_estimator(self.config.checkpoint, est)  # type: ignore[union-attr]
        except (OSError, SudsError) as exc:
            self._log("error", f"cannot write checkpoint {self.config.checkpoint}: {exc}")
            return
        self._saved_at = mark

    def close(self) -> SudsModel | None:
        """At shutdown: save the checkpoint; returns the final model if it changed since the last one."""
        self._drain()
        model = self._take_model() if self._dirty else None
        self.save_checkpoint()
        return model
