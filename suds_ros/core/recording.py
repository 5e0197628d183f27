"""The in-memory form of one recording: shape and pose time series plus metadata.

Every layer exchanges :class:`Recording`: the bag reader produces it, the
simulator produces it, the identifier and the diagnosis consume it.  It is
validated on construction, so code that receives one can trust its shapes,
ordering and finiteness.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from suds_ros.core._typing import BoolArray, FloatArray, IntArray
from suds_ros.core.errors import NO_POSE, TOO_LITTLE_DATA, SudsDataError

#: How far (s, absolute) a stamp may lie outside the pose stream's span in :meth:`Recording.pose_at`
#: and still get the end pose: a few float64 rounding steps of an epoch stamp (~2.4e-7 s at 1.7e9 s).
POSE_SPAN_TOL = 1e-6


def joint_names(n_joints: int) -> tuple[str, ...]:
    """The package's joint names for a chain of ``n_joints`` joints: ``("joint_1", …)``, head to tail."""
    return tuple(f"joint_{j + 1}" for j in range(n_joints))


def samples_per_cycle(dt: float, gait_hz: float) -> int:
    """Whole samples per gait cycle at sample interval ``dt`` (s) and gait frequency ``gait_hz`` (Hz)."""
    return int(round(1.0 / (gait_hz * dt)))


def stream_period(t: FloatArray) -> float:
    """A stream's sampling period from its stamps ``t`` (s), robust to lost messages and stamp jitter.

    The median interval is the period while few messages are lost, but it drifts up with the
    losses long before half of them are gone: with 45 % of a 100 Hz stream lost and 1 ms of stamp
    jitter it is 20 % long, and a grid counted in it puts a run of four lost samples at four
    periods instead of five.  The intervals between two messages received in a row form the
    lowest cluster: starting from the median of the intervals up to 1.5 times the lower quartile,
    the period is the median of the intervals within half a period of it, taken again until it
    settles (a window symmetric about the period, so stamp jitter does not bias it).  Every
    interval of an unbroken stream, the unbroken pairs of a lossy one.

    Raises
    ------
    SudsDataError
        (code ``too_little_data``) fewer than two distinct stamps.
    """
    d = np.diff(np.asarray(t, dtype=float))
    d = d[d > 0]
    if d.size == 0:
        raise SudsDataError(f"`t`: expected at least 2 distinct stamps, got {np.size(t)} stamp(s) with none apart",
                            code=TOO_LITTLE_DATA)
    period = float(np.median(d[d <= 1.5 * np.quantile(d, 0.25)]))
    for _ in range(PERIOD_ITERATIONS):
        again = float(np.median(d[(d >= 0.5 * period) & (d <= 1.5 * period)]))
        if again == period:
            break
        period = again
    return period


#: at most this many re-centrings of :func:`stream_period`'s window
PERIOD_ITERATIONS = 20


def _check_stamps(name: str, t: FloatArray) -> None:
    if t.ndim != 1:
        raise SudsDataError(f"{name}: expected a 1-D array of stamps, got shape {t.shape}")
    if t.size and not np.all(np.isfinite(t)):
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise SudsDataError(f"{name}: stamp {bad} is not finite ({t[bad]!r})")
    d = np.diff(t)
    if np.any(d == 0):
        k = int(np.flatnonzero(d == 0)[0])
        raise SudsDataError(f"{name}: duplicate stamp {t[k]:.9f} s at samples {k} and {k + 1}")
    if np.any(d < 0):
        k = int(np.flatnonzero(d < 0)[0])
        raise SudsDataError(
            f"{name}: stamps are not sorted: sample {k + 1} ({t[k + 1]:.9f} s) "
            f"comes before sample {k} ({t[k]:.9f} s)"
        )


def _check_finite(name: str, a: FloatArray, t: FloatArray) -> None:
    if not np.all(np.isfinite(a)):
        row = int(np.flatnonzero(~np.all(np.isfinite(a.reshape(a.shape[0], -1)), axis=1))[0])
        raise SudsDataError(f"{name}: sample {row} (stamp {t[row]:.9f} s) contains NaN or Inf")


@dataclass(frozen=True)
class Recording:
    """Shape and body-pose time series of one run.

    Attributes
    ----------
    t : (n,) float
        Shape sample stamps, seconds (absolute; need not start at 0), strictly increasing.
    r : (n, nj) float
        Joint values: angles in rad (or lengths in m for prismatic systems), columns
        ordered as ``joint_names``.
    joint_names : tuple of str
        Names of the nj joints, head to tail.
    actuated, passive : tuple of str
        Names of the actuated and passive joints (disjoint subsets of ``joint_names``;
        their union is all joints).
    pose_t : (m,) float
        Body-pose stamps, seconds, strictly increasing.
    pose : (m, 3) float
        Body frame in the world: x (m), y (m), yaw (rad, unwrapped on construction).
    system : str
        System id (``purcell3``, ``swimmer9``, ``linear_passive``, ``pushmepullyou`` or a user id).
    gait_hz : float or None
        Nominal gait frequency, Hz, if known.
    effort : (n, nj) float or None
        Recorded joint efforts (N·m), if any.
    bouts : tuple of (t_first, t_last)
        Steady stretches of intermittent motion (stamps, s; in time order, disjoint), as ``suds
        import --segment`` finds them and the metadata key ``bouts`` holds; empty: the whole
        recording is one steady run.  Identification then trains and tests on whole bouts.
    truth : dict
        Optional ground truth from a simulator, never written to bags: ``"xi"`` (n, 3)
        body velocity, ``"rdot"`` (n, nj) shape velocity, ``"phase"`` (n,) reference phase
        in rad, ``"tau"`` (n, nj) joint torques.
    bridged : (n,) bool or None
        Shape samples that were not measured but bridged across a run of lost samples
        (:func:`~suds_ros.core.resample.on_shape_grid` sets it; None: every sample measured).
        The identifier fits and scores no interval that touches one.
    """

    t: FloatArray
    r: FloatArray
    joint_names: tuple[str, ...]
    actuated: tuple[str, ...]
    passive: tuple[str, ...]
    pose_t: FloatArray
    pose: FloatArray
    system: str = "unknown"
    gait_hz: float | None = None
    effort: FloatArray | None = None
    bouts: tuple[tuple[float, float], ...] = ()
    truth: dict[str, FloatArray] = field(default_factory=dict, compare=False, repr=False)
    bridged: BoolArray | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        r = np.asarray(self.r, dtype=float)
        pt = np.asarray(self.pose_t, dtype=float)
        pose = np.asarray(self.pose, dtype=float)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "pose_t", pt)
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "actuated", tuple(self.actuated))
        object.__setattr__(self, "passive", tuple(self.passive))
        _check_stamps("shape stamps", t)
        _check_stamps("pose stamps", pt)
        if r.ndim != 2 or r.shape[0] != t.size:
            raise SudsDataError(
                f"shape: expected an array of shape ({t.size}, n_joints), got {r.shape}"
            )
        if r.shape[1] != len(self.joint_names):
            raise SudsDataError(
                f"shape: {r.shape[1]} joint columns but {len(self.joint_names)} joint names "
                f"{list(self.joint_names)}"
            )
        if pose.ndim != 2 or pose.shape != (pt.size, 3):
            raise SudsDataError(f"pose: expected shape ({pt.size}, 3), got {pose.shape}")
        _check_finite("shape", r, t)
        _check_finite("pose", pose, pt)
        names = set(self.joint_names)
        if len(names) != len(self.joint_names):
            raise SudsDataError(f"joint names are not unique: {list(self.joint_names)}")
        for role, group in (("actuated", self.actuated), ("passive", self.passive)):
            unknown = [j for j in group if j not in names]
            if unknown:
                raise SudsDataError(
                    f"{role} joints {unknown} are not among the recorded joints "
                    f"{list(self.joint_names)}"
                )
        overlap = set(self.actuated) & set(self.passive)
        if overlap:
            raise SudsDataError(f"joints {sorted(overlap)} are listed as both actuated and passive")
        missing = names - set(self.actuated) - set(self.passive)
        if missing:
            raise SudsDataError(
                f"joints {sorted(missing)} are neither actuated nor passive; "
                "give every joint a role"
            )
        if not self.actuated:
            raise SudsDataError("no actuated joint: a SUDS model needs at least one driven joint")
        bouts = tuple((float(a), float(b)) for a, b in self.bouts)
        for k, (a, b) in enumerate(bouts):
            if not (np.isfinite(a) and np.isfinite(b) and a <= b) or (k and a <= bouts[k - 1][1]):
                raise SudsDataError(f"bouts: expected (t_first, t_last) pairs with t_first ≤ t_last, in time "
                                    f"order without overlap, got {list(self.bouts)!r}")
        object.__setattr__(self, "bouts", bouts)
        if pose.size:
            pose = pose.copy()
            pose[:, 2] = np.unwrap(pose[:, 2])
        object.__setattr__(self, "r", r)
        object.__setattr__(self, "pose", pose)
        if self.bridged is not None:
            bridged = np.asarray(self.bridged, dtype=bool)
            if bridged.shape != t.shape:
                raise SudsDataError(f"bridged: expected shape {t.shape}, got {bridged.shape}")
            object.__setattr__(self, "bridged", bridged)
        if self.effort is not None:
            eff = np.asarray(self.effort, dtype=float)
            if eff.shape != r.shape:
                raise SudsDataError(f"effort: expected shape {r.shape}, got {eff.shape}")
            _check_finite("effort", eff, t)
            object.__setattr__(self, "effort", eff)

    # ------------------------------------------------------------------ views
    @property
    def n_samples(self) -> int:
        """Number of shape samples."""
        return int(self.t.size)

    @property
    def actuated_index(self) -> IntArray:
        """Column indices of the actuated joints in ``r``, shape (na,)."""
        return np.array([self.joint_names.index(j) for j in self.actuated], dtype=np.int64)

    @property
    def passive_index(self) -> IntArray:
        """Column indices of the passive joints in ``r``, shape (np,)."""
        return np.array([self.joint_names.index(j) for j in self.passive], dtype=np.int64)

    @property
    def r_a(self) -> FloatArray:
        """Actuated joint values, shape (n, na)."""
        return self.r[:, self.actuated_index]

    @property
    def r_p(self) -> FloatArray:
        """Passive joint values, shape (n, np)."""
        return self.r[:, self.passive_index]

    @property
    def dt(self) -> float:
        """The shape stream's sampling period, s (:func:`stream_period`: the median interval, robust to losses)."""
        if self.t.size < 2:
            raise SudsDataError("recording has fewer than 2 shape samples")
        return stream_period(self.t)

    def pose_at(self, t: FloatArray) -> FloatArray:
        """Body pose interpolated at stamps ``t`` (s), shape (len(t), 3): x, y, yaw.

        Linear interpolation of x, y and unwrapped yaw between the two pose samples around each
        stamp.  A stamp more than :data:`POSE_SPAN_TOL` (1 µs, absolute: the same on stamps near
        0 and on epoch stamps ~1.7e9 s) outside ``[pose_t[0], pose_t[-1]]`` raises
        :class:`SudsDataError` (code ``no_pose``): no pose is held or extrapolated.  Within the
        tolerance the end pose is used (it moves < 1 µs × the body speed).
        """
        t = np.asarray(t, dtype=float)
        if self.pose_t.size < 2:
            raise SudsDataError(f"`pose_t`: expected at least 2 pose samples, got {self.pose_t.size}",
                                code=NO_POSE)
        lo, hi = self.pose_t[0], self.pose_t[-1]
        if t.size and (t.min() < lo - POSE_SPAN_TOL or t.max() > hi + POSE_SPAN_TOL):
            outside = int(np.count_nonzero((t < lo - POSE_SPAN_TOL) | (t > hi + POSE_SPAN_TOL)))
            raise SudsDataError(
                f"`t`: expected stamps within the pose stream's span [{lo:.6f}, {hi:.6f}] s "
                f"(± {POSE_SPAN_TOL:g} s), got {outside} of {t.size} outside it "
                f"(they reach [{t.min():.6f}, {t.max():.6f}] s); no pose is extrapolated",
                code=NO_POSE,
            )
        return np.stack([np.interp(t, self.pose_t, self.pose[:, i]) for i in range(3)], axis=1)

    def slice(self, start: int, stop: int) -> "Recording":
        """Samples ``start:stop`` of the shape stream, with the pose samples in the same window."""
        t = self.t[start:stop]
        if t.size == 0:
            raise SudsDataError(f"empty slice [{start}:{stop}] of {self.n_samples} samples")
        m = (self.pose_t >= t[0]) & (self.pose_t <= t[-1])
        truth = {k: v[start:stop] for k, v in self.truth.items()}
        return replace(
            self,
            t=t,
            r=self.r[start:stop],
            pose_t=self.pose_t[m],
            pose=self.pose[m],
            effort=None if self.effort is None else self.effort[start:stop],
            truth=truth,
            bridged=None if self.bridged is None else self.bridged[start:stop],
        )
