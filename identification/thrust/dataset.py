"""Thrust data set from a flight log (paper 000 section 4), the Pearson gate, and k of eq. 6.

Measured thrust: on a quadrotor the rotors push along body -z, so ``F_z = -accel_body_z_m_s2 * mass_kg``
[N, positive up] is the summed rotor thrust minus the body-z drag (small at hover speeds). The
accelerometer (50-1000 Hz) is averaged over each motor-PWM sample interval ``[t_k + lag, t_{k+1} + lag)``
(10-50 Hz), so every PWM sample gets the mean specific force while that command was applied. The lag (the
accelerometer's delay behind the command: motor/ESC response plus logging skew) is estimated as the one
that maximises the Pearson correlation of summed PWM with F_z, and reported; a negative one (the accelerometer
ahead of the commands, which no motor does) is kept and stated: the vertical drag in ``-m a_z`` (it follows the
climb rate, which leads the thrust in a climbing and sinking flight) or a logging skew moves it there.

With a known vertical drag coefficient (``vertical_drag_N_s_m``, e.g. ``kd_z_N_s_m`` from ``uavfmu identify
quadrotor``) the measured thrust is ``-m a_z - kd_z w`` (``w`` the body-z velocity: the logged NED velocity
rotated by the logged attitude), the rotor thrust itself.

Only airborne samples enter: armed, every motor above ``motor_min_pwm_us`` and, when the log has
``altitude_m``, higher than ``min_altitude_m`` above home. On the ground the accelerometer reads 1 g
whatever the motors do; those samples would flatten the map (on the ArduCopter log of ../shared/data the
Pearson correlation is 0.38 with the ground run-up included and 0.75 without).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import MISSING, dataclass, field
from typing import Any, NamedTuple

import numpy as np

from fmu_models.common.units import RPM_TO_RAD_S
from fmu_models.config import bounded, range_problems
from fmu_models.quadrotor.anfis import AnfisMap
from fmu_models.quadrotor.constants import N_MOTORS, PWM_IDLE_US
from identification.logs.log_state import BODY_VELOCITY_SIGNALS, body_velocity

PAPER_MIN_PEARSON = 0.85  #: paper 000 section 4: correlation needed "to proceed a good training"
#: a motor PWM above this [us] counts as spinning for flight (ArduCopter spins its motors near 1100-1150 us armed)
MOTOR_MIN_PWM_US = 1150.0
GAP_FACTOR = 3.0  #: a PWM sample interval longer than this many median intervals starts a new segment
LOWPASS_ORDER = 2  #: Butterworth order of the optional zero-phase low-pass filter
MOTOR_SIGNAL = "motor_{k}_pwm_us"
EXTRA_INPUTS = ("climb_rate_m_s", "battery_voltage_V")
#: log signal names tried, in order, for each extra input (readers name the battery voltage battery_voltage_v)
LOG_NAMES = {"battery_voltage_V": ("battery_voltage_v", "battery_voltage_V")}


class ThrustDataError(ValueError):
    """The log cannot give a thrust data set (the message names the log, signal and values)."""


class CorrelationGateError(ValueError):
    """The training inputs correlate too weakly with F_z for the paper's gate; ``correlations`` has r."""

    def __init__(self, message: str, correlations: dict[str, float]) -> None:
        super().__init__(message)
        self.correlations = dict(correlations)


#: samples dropped after every take-off and before every touch-down [s] (landing gear on the ground, motors on)
EDGE_GUARD_S = 1.0


@dataclass(frozen=True)
class ThrustDatasetConfig:
    """How to cut a thrust data set from a log (checked at construction).

    ``lag_s``: accelerometer delay behind the PWM command [s]; ``None`` estimates it within
    ``+-max_lag_s``. ``lowpass_hz``: cut-off of a zero-phase Butterworth filter applied to every aligned
    series per segment (``None``: no filter). ``extra_inputs``: more candidate inputs, used when logged.
    ``edge_guard_s``: samples this close to the start or end of an airborne segment are dropped: at
    take-off and touch-down the landing gear touches the ground while the motors still run (a barometric
    altitude lags), and the accelerometer then measures contact forces, not thrust.
    """

    mass_kg: float = bounded(MISSING, 0.05, 50.0, "kg")
    n_motors: int = bounded(4, 1, 12)
    motor_min_pwm_us: float = bounded(MOTOR_MIN_PWM_US, 800.0, 2200.0, "us")
    min_altitude_m: float = bounded(0.5, -100.0, 1000.0, "m")
    min_segment_s: float = bounded(2.0, 0.0, 3600.0, "s")
    lag_s: float | None = bounded(None, -5.0, 5.0, "s (None: estimate)", optional=True)
    max_lag_s: float = bounded(0.3, 0.0, 5.0, "s")
    lowpass_hz: float | None = bounded(None, 1e-3, 1000.0, "Hz (None: no filter)", optional=True)
    extra_inputs: tuple[str, ...] = EXTRA_INPUTS
    pwm_idle_us: float = bounded(PWM_IDLE_US, 800.0, 1500.0, "us")
    edge_guard_s: float = bounded(EDGE_GUARD_S, 0.0, 60.0, "s")  #: dropped at both ends of every airborne segment
    airborne_on_mean_pwm: bool = False  #: airborne test on the mean motor PWM instead of every motor
    #: known vertical drag coefficient [N s/m]: the measured thrust becomes ``-m a_z - kd_z w`` (None: ``-m a_z``)
    vertical_drag_N_s_m: float | None = bounded(None, 0.0, 100.0, "N s/m (None: no drag correction)", optional=True)

    def __post_init__(self) -> None:
        problems = range_problems(self)
        for name in self.extra_inputs:
            if name not in EXTRA_INPUTS:
                problems.append(f"extra input {name!r} is not supported; allowed: {', '.join(EXTRA_INPUTS)}")
        if problems:
            raise ThrustDataError("thrust data set options: " + "; ".join(problems))


@dataclass(frozen=True)
class ThrustDataset:
    """Aligned airborne samples, one per motor-PWM sample, in time order.

    ``inputs`` maps candidate input names to arrays: ``pwm_sum_us``, ``motor_<k>_pwm_us`` and, when
    logged, the extra inputs. ``fz_N``: measured thrust [N, up]. ``segment``: index of the airborne
    segment of each sample. ``lag_curve``: (lags [s], Pearson r) of the lag search (empty if fixed).
    """

    time_s: np.ndarray
    inputs: dict[str, np.ndarray]
    fz_N: np.ndarray
    segment: np.ndarray
    lag_s: float
    lag_estimated: bool
    lag_curve: tuple[tuple[float, ...], tuple[float, ...]]
    sample_period_s: float
    notes: tuple[str, ...] = field(default=())
    source: str = ""

    @property
    def n_samples(self) -> int:
        return int(self.fz_N.size)

    @property
    def pwm_sum_us(self) -> np.ndarray:
        return self.inputs["pwm_sum_us"]

    def subset(self, mask: np.ndarray) -> ThrustDataset:
        """The samples where ``mask`` (bool, or index array) selects."""
        return ThrustDataset(
            time_s=self.time_s[mask],
            inputs={k: v[mask] for k, v in self.inputs.items()},
            fz_N=self.fz_N[mask],
            segment=self.segment[mask],
            lag_s=self.lag_s,
            lag_estimated=self.lag_estimated,
            lag_curve=self.lag_curve,
            sample_period_s=self.sample_period_s,
            notes=self.notes,
            source=self.source,
        )

    def split(self, train_fraction: float) -> tuple[ThrustDataset, ThrustDataset]:
        """First ``train_fraction`` of the samples (time order) and the rest."""
        if not 0.0 < train_fraction < 1.0:
            raise ThrustDataError(f"train fraction = {train_fraction}; allowed (0, 1)")
        n_train = round(train_fraction * self.n_samples)
        idx = np.arange(self.n_samples)
        return self.subset(idx < n_train), self.subset(idx >= n_train)

    def correlations(self) -> dict[str, float]:
        """Pearson r of every candidate input with F_z (NaN for a constant input)."""
        return {name: pearson(x, self.fz_N) for name, x in self.inputs.items()}


# --------------------------------------------------------------------------- small numeric helpers
def pearson(x: np.ndarray, y: np.ndarray) -> float:
    """Pearson correlation coefficient; NaN when either series is constant or there are < 3 samples."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if x.size < 3 or np.ptp(x) == 0.0 or np.ptp(y) == 0.0:
        return float("nan")
    return float(np.corrcoef(x, y)[0, 1])


def interval_means(t_s: np.ndarray, v: np.ndarray, edges_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean of samples ``v(t_s)`` in each ``[edges_s[k], edges_s[k+1])`` and their count (NaN if none).

    ``t_s`` must be sorted. Vectorised with a cumulative sum and two binary searches.
    """
    csum = np.concatenate([[0.0], np.cumsum(v)])
    i0 = np.searchsorted(t_s, edges_s[:-1], side="left")
    i1 = np.searchsorted(t_s, edges_s[1:], side="left")
    count = i1 - i0
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, (csum[i1] - csum[i0]) / np.maximum(count, 1), np.nan)
    return mean, count


def interleaved_blocks(n: int, block_len: int, every: int = 5) -> np.ndarray:
    """Bool mask picking every ``every``-th block of ``block_len`` consecutive samples (checking data).

    Blocks rather than single samples, so neighbouring (correlated) samples do not sit on both sides.
    """
    if block_len < 1 or every < 2:
        raise ValueError(f"block_len = {block_len} (>= 1) and every = {every} (>= 2) are required")
    return (np.arange(n) // block_len) % every == every - 1


# --------------------------------------------------------------------------- log access
def _series(log: Any, name: str) -> tuple[np.ndarray, np.ndarray] | None:
    """``(t_s, values)`` of signal ``name`` of a FlightLog, sorted by time, or None when not logged."""
    try:
        sig = log.signal(name)
    except KeyError:
        return None
    if isinstance(sig, tuple) and len(sig) == 2:
        t, v = sig
    else:
        t = next((getattr(sig, a) for a in ("t_s", "time_s", "t") if hasattr(sig, a)), None)
        v = next((getattr(sig, a) for a in ("values", "value", "v", "data") if hasattr(sig, a)), None)
        if t is None or v is None:
            raise ThrustDataError(f"signal {name!r}: unexpected type {type(sig).__name__} (no time/values)")
    t = np.asarray(t, float).ravel()
    v = np.asarray(v, float).ravel()
    ok = np.isfinite(t) & np.isfinite(v)
    t, v = t[ok], v[ok]
    order = np.argsort(t, kind="stable")
    return t[order], v[order]


def _hold(t_s: np.ndarray, v: np.ndarray, at_s: np.ndarray) -> np.ndarray:
    """Zero-order hold of ``v(t_s)`` at times ``at_s`` (value before the first sample: the first)."""
    i = np.searchsorted(t_s, at_s, side="right") - 1
    return v[np.clip(i, 0, v.size - 1)]


def _segments(mask: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """Segment id per sample: runs of ``mask`` not interrupted by a gap; -1 where mask is False."""
    start = mask & ~np.concatenate([[False], mask[:-1] & ~gap[:-1]])
    seg = np.cumsum(start) - 1
    return np.where(mask, seg, -1)


def _lowpass(x: np.ndarray, seg: np.ndarray, fs_hz: float, cutoff_hz: float) -> np.ndarray:
    """Zero-phase Butterworth low-pass (scipy ``filtfilt``) of ``x`` within each segment."""
    if cutoff_hz >= fs_hz / 2.0:
        raise ThrustDataError(
            f"lowpass_hz = {cutoff_hz} must be below the Nyquist frequency {fs_hz / 2.0:.3g} Hz "
            "of the PWM log"
        )
    from scipy import signal  # here, not at import: scipy.signal is slow to import, and every `uavfmu identify`
    # parser (also `--help`) imports this module for its defaults

    b, a = signal.butter(LOWPASS_ORDER, cutoff_hz, fs=fs_hz)
    out = x.copy()
    for s in np.unique(seg):
        idx = seg == s
        out[idx] = signal.filtfilt(b, a, x[idx], padlen=min(3 * max(len(a), len(b)), int(idx.sum()) - 1))
    return out


@dataclass(frozen=True)
class _PwmGrid:
    """Motor PWM on the first motor's sample times: one interval ``[lo_s, hi_s)`` per sample.

    ``pwm_us`` (N, n_motors), zero-order held; ``gap``: the interval after a sample is a log gap (its
    ``hi_s`` is then one median period after ``lo_s``).
    """

    t_s: np.ndarray
    pwm_us: np.ndarray
    period_s: float
    gap: np.ndarray
    hi_s: np.ndarray


class _LagFit(NamedTuple):
    """Accelerometer lag behind the PWM [s], whether it was estimated, and the search's (lags, r) curve."""

    lag_s: float
    lag_estimated: bool
    lag_curve: tuple[tuple[float, ...], tuple[float, ...]]


def build_thrust_dataset(log: Any, config: ThrustDatasetConfig, source: str = "") -> ThrustDataset:
    """Airborne, aligned (PWM, F_z) samples of ``log`` (a ``FlightLog``); see the module docstring."""
    src = source or str(getattr(log, "path", "") or "flight log")
    notes: list[str] = []
    motors = _motor_series(log, config.n_motors, src)
    acc = _series(log, "accel_body_z_m_s2")
    if acc is None or acc[0].size < 2:
        raise ThrustDataError(f"{src}: signal 'accel_body_z_m_s2' (IMU specific force) is not in the log")
    grid = _pwm_grid(motors, src)
    mask, alt_logged = _airborne(log, config, grid, notes)
    if config.vertical_drag_N_s_m is not None:
        acc = (acc[0], acc[1] + config.vertical_drag_N_s_m * _body_z_velocity(log, acc[0], src) / config.mass_kg)
        notes.append(f"measured thrust -m a_z - kd_z w with the given vertical drag kd_z = "
                     f"{config.vertical_drag_N_s_m:g} N s/m (w: logged NED velocity rotated by the logged attitude)")
    fz_of_lag = _fz_aligner(acc, grid.t_s, grid.hi_s, config.mass_kg)
    pwm_sum = grid.pwm_us.sum(axis=1)
    lag = _fit_lag(config, float(np.median(np.diff(acc[0]))), fz_of_lag, pwm_sum, mask)
    if lag.lag_estimated and lag.lag_s < 0.0:
        notes.append(f"the delay search puts the accelerometer {-lag.lag_s:.3g} s AHEAD of the motor commands, which "
                     "no motor does: the vertical drag in -m a_z (it follows the climb rate; give the vertical drag "
                     "coefficient to remove it) or a logging skew between the two moves the best correlation there, "
                     "and the thrust map may carry that error")
    fz = fz_of_lag(lag.lag_s)
    mask = _trim_edges(mask & np.isfinite(fz), grid, config.edge_guard_s, notes)
    mask, seg = _drop_short_segments(mask, grid, config.min_segment_s, notes)
    if mask.sum() < 10:
        raise ThrustDataError(
            f"{src}: only {int(mask.sum())} airborne samples (armed, "
            f"{'mean motor PWM' if config.airborne_on_mean_pwm else 'all motors'} > {config.motor_min_pwm_us} us"
            f"{', altitude > ' + str(config.min_altitude_m) + ' m' if alt_logged else ''}); "
            "nothing to train on"
        )
    inputs = _candidate_inputs(log, config, grid, mask, src, notes)
    out_fz, out_seg = fz[mask], seg[mask]
    if config.lowpass_hz is not None:
        fs = 1.0 / grid.period_s
        inputs = {k: _lowpass(v, out_seg, fs, config.lowpass_hz) for k, v in inputs.items()}
        out_fz = _lowpass(out_fz, out_seg, fs, config.lowpass_hz)
    return ThrustDataset(
        time_s=grid.t_s[mask],
        inputs=inputs,
        fz_N=out_fz,
        segment=out_seg,
        sample_period_s=grid.period_s,
        notes=tuple(notes),
        source=src,
        **lag._asdict(),
    )


def _motor_series(log: Any, n_motors: int, src: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(t_s, pwm_us)`` of motors 1..``n_motors``; ThrustDataError naming the first one not logged."""
    motors = []
    for k in range(1, n_motors + 1):
        s = _series(log, MOTOR_SIGNAL.format(k=k))
        if s is None:
            raise ThrustDataError(
                f"{src}: signal {MOTOR_SIGNAL.format(k=k)!r} is not in the log; a thrust data set needs the "
                f"PWM of all {n_motors} motors"
            )
        motors.append(s)
    return motors


def _pwm_grid(motors: list[tuple[np.ndarray, np.ndarray]], src: str) -> _PwmGrid:
    """Every motor's PWM held on the first motor's sample times, with the sample intervals and log gaps."""
    t_pwm = motors[0][0]
    if t_pwm.size < 3:
        raise ThrustDataError(f"{src}: only {t_pwm.size} motor PWM samples")
    pwm = np.stack([_hold(t, v, t_pwm) if t is not t_pwm else v for t, v in motors], axis=1)
    dt = np.diff(t_pwm)
    period = float(np.median(dt))
    if not period > 0.0:
        raise ThrustDataError(f"{src}: motor PWM timestamps do not increase (median step {period} s)")
    dt_next = np.concatenate([dt, [period]])
    gap = dt_next > GAP_FACTOR * period
    return _PwmGrid(t_pwm, pwm, period, gap, t_pwm + np.where(gap, period, dt_next))


def _airborne(
    log: Any, config: ThrustDatasetConfig, grid: _PwmGrid, notes: list[str]
) -> tuple[np.ndarray, bool]:
    """Airborne mask (armed, motors above the threshold, above ``min_altitude_m``) and whether altitude is logged."""
    if config.airborne_on_mean_pwm:  # aggressive flight drives single motors to their minimum in the air
        mask = grid.pwm_us.mean(axis=1) > config.motor_min_pwm_us
    else:
        mask = np.all(grid.pwm_us > config.motor_min_pwm_us, axis=1)
    armed = _series(log, "armed")
    if armed is None:
        notes.append("no 'armed' signal: airborne samples found from motor PWM (and altitude) only")
    else:
        mask &= _hold(*armed, grid.t_s) > 0.5
    alt = _series(log, "altitude_m")
    if alt is None:
        notes.append(
            "no 'altitude_m' signal: ground samples with spinning motors cannot be excluded; F_z there is "
            "the weight, not the thrust"
        )
    else:
        mask &= np.interp(grid.t_s, *alt) > config.min_altitude_m
    return mask, alt is not None


def _fit_lag(
    config: ThrustDatasetConfig,
    acc_step_s: float,
    fz_of_lag: Callable[[float], np.ndarray],
    pwm_sum: np.ndarray,
    mask: np.ndarray,
) -> _LagFit:
    """The given lag, or the one in ``+-max_lag_s`` (accelerometer steps) maximising r(summed PWM, F_z)."""
    if config.lag_s is not None:
        return _LagFit(float(config.lag_s), False, ((), ()))
    n_steps = round(config.max_lag_s / acc_step_s) if acc_step_s > 0 else 0
    lags = np.arange(-n_steps, n_steps + 1) * acc_step_s
    rs = []
    for lag in lags:  # a few dozen candidate lags, each one vectorised over all samples
        fz = fz_of_lag(lag)
        ok = mask & np.isfinite(fz)
        rs.append(pearson(pwm_sum[ok], fz[ok]))
    r_arr = np.nan_to_num(np.array(rs), nan=-np.inf)
    lag_s = float(lags[int(np.argmax(r_arr))])
    return _LagFit(lag_s, True, (tuple(float(v) for v in lags), tuple(float(v) for v in rs)))


def _trim_edges(mask: np.ndarray, grid: _PwmGrid, guard_s: float, notes: list[str]) -> np.ndarray:
    """``mask`` without the samples within ``guard_s`` of a take-off or touch-down: the start (end) of an
    airborne segment that follows (precedes) at least ``guard_s`` on the ground or the log's start (end).
    Short dips in between (an aggressive descent at low PWM) are not ground contacts and keep their edges."""
    if guard_s <= 0.0 or not mask.any():
        return mask
    seg = _segments(mask, grid.gap)
    ids = seg[mask]
    t, t_hi = grid.t_s[mask], grid.hi_s[mask]
    n = ids.max() + 1
    first, last = np.full(n, np.inf), np.full(n, -np.inf)
    np.minimum.at(first, ids, t)
    np.maximum.at(last, ids, t_hi)
    ground_before = np.concatenate([[np.inf], first[1:] - last[:-1]]) >= guard_s
    ground_after = np.concatenate([first[1:] - last[:-1], [np.inf]]) >= guard_s
    drop = (ground_before[ids] & (t < first[ids] + guard_s)) | (ground_after[ids] & (t_hi > last[ids] - guard_s))
    out = mask.copy()
    out[np.flatnonzero(mask)[drop]] = False
    if drop.any():
        notes.append(f"dropped {int(drop.sum())} samples within {guard_s} s of take-off or touch-down "
                     "(ground contact)")
    return out


def without_ground_contact(airborne: np.ndarray, t_s: np.ndarray, guard_s: float | None = None) -> np.ndarray:
    """``airborne`` on a regular time grid ``t_s`` [s] (a replay's) without the samples within ``guard_s``
    (default :data:`EDGE_GUARD_S`, ``ThrustDatasetConfig.edge_guard_s``'s) of a take-off or touch-down, as the data set
    drops them (:func:`_trim_edges`), so a replay's hover battery state sees the samples identification saw."""
    t = np.asarray(t_s, float)
    mask = np.asarray(airborne, bool)
    if t.size < 2:
        return mask
    period = float(np.median(np.diff(t)))
    grid = _PwmGrid(t, np.empty((t.size, 0)), period, np.zeros(t.size, bool), t + period)
    return _trim_edges(mask, grid, EDGE_GUARD_S if guard_s is None else guard_s, [])


def _drop_short_segments(
    mask: np.ndarray, grid: _PwmGrid, min_segment_s: float, notes: list[str]
) -> tuple[np.ndarray, np.ndarray]:
    """``mask`` without airborne segments shorter than ``min_segment_s`` (and 4 samples), and segment ids."""
    seg = _segments(mask, grid.gap)
    if mask.any():
        ids, counts = np.unique(seg[mask], return_counts=True)
        short = ids[counts * grid.period_s < max(min_segment_s, 4 * grid.period_s)]
        if short.size:
            notes.append(f"dropped {short.size} airborne segment(s) shorter than {min_segment_s} s")
            mask = mask & ~np.isin(seg, short)
            seg = _segments(mask, grid.gap)
    return mask, seg


def _candidate_inputs(
    log: Any, config: ThrustDatasetConfig, grid: _PwmGrid, mask: np.ndarray, src: str, notes: list[str]
) -> dict[str, np.ndarray]:
    """Summed PWM, each motor's PWM and the logged extra inputs (at interval mid-points) where ``mask``."""
    inputs: dict[str, np.ndarray] = {"pwm_sum_us": grid.pwm_us.sum(axis=1)[mask]}
    for k in range(config.n_motors):
        inputs[MOTOR_SIGNAL.format(k=k + 1)] = grid.pwm_us[mask, k]
    mid = (grid.t_s + grid.hi_s)[mask] / 2.0
    for name in config.extra_inputs:
        s = _extra_series(log, name, src)
        if s is None or s[0].size < 2:
            notes.append(f"candidate input {name!r} is not logged; left out")
            continue
        inputs[name] = np.interp(mid, *s)
    return inputs


def _extra_series(log: Any, name: str, src: str) -> tuple[np.ndarray, np.ndarray] | None:
    """The first logged signal for extra input ``name``; a battery voltage with no valid value is an error."""
    for log_name in LOG_NAMES.get(name, (name,)):
        try:
            raw = log.signal(log_name)
        except KeyError:
            continue
        s = _series(log, log_name)
        if name == "battery_voltage_V":
            n_raw = int(np.size(getattr(raw, "values", raw[1] if isinstance(raw, tuple) else [])))
            ok = s[1] > 0.0 if s is not None else np.zeros(0, bool)
            if not ok.any():
                raise ThrustDataError(
                    f"{src}: field {log_name!r}: all {n_raw} battery voltage samples are zero or NaN; "
                    "allowed: > 0 V. Fix the log's battery monitor or drop the voltage (--no-voltage)"
                )
            s = (s[0][ok], s[1][ok])
        return s
    return None


def _body_z_velocity(log: Any, t_s: np.ndarray, src: str) -> np.ndarray:
    """Body-z velocity [m/s, down positive] at ``t_s``: the logged NED velocity rotated by the logged attitude."""
    series = {n: _series(log, n) for n in BODY_VELOCITY_SIGNALS}
    missing = [n for n, v in series.items() if v is None or v[0].size < 2]
    if missing:
        raise ThrustDataError(f"{src}: a vertical drag correction needs {', '.join(missing)}, not in the log")
    return body_velocity(series, t_s)[:, 2]  # type: ignore[arg-type]


def _fz_aligner(
    acc: tuple[np.ndarray, np.ndarray], lo_s: np.ndarray, hi_s: np.ndarray, mass_kg: float
) -> Callable[[float], np.ndarray]:
    """``lag -> F_z`` [N] per PWM interval: -mass * mean accel_body_z over ``[lo + lag, hi + lag)``."""
    t_acc, a_z = acc

    def fz(lag_s: float) -> np.ndarray:
        edges = np.empty(lo_s.size * 2)
        edges[0::2] = lo_s + lag_s
        edges[1::2] = hi_s + lag_s
        # intervals may have gaps between them (log gaps): evaluate every [lo, hi) pair, drop the gaps
        mean, _ = interval_means(t_acc, a_z, edges)
        return -mass_kg * mean[0::2]

    return fz


# --------------------------------------------------------------------------- damaged logs
def damage_gate(log: Any, accept: bool) -> tuple[str, ...]:
    """Refuse (``LogError``) a log damaged beyond the limit, naming ``--accept-damaged-log``; with ``accept``,
    return the sentence saying what was overridden."""
    from identification.logs.flightlog import LogError, check_quality

    try:
        check_quality(log)
    except LogError as err:
        message = str(err).replace("pass --force", "pass --accept-damaged-log")
        if not accept:
            raise LogError(message) from None
        return (f"--accept-damaged-log: using {message.split(': ', 1)[0]} although "
                f"{message.split(': ', 1)[-1].split('. Repair')[0]}",)
    return ()


# --------------------------------------------------------------------------- the paper's gate
def check_gate(
    correlations: dict[str, float],
    inputs: tuple[str, ...],
    threshold: float = PAPER_MIN_PEARSON,
    force: bool = False,
    source: str = "",
) -> list[str]:
    """Refuse (``CorrelationGateError``) when a training input's Pearson r with F_z is below ``threshold``.

    With ``force`` (``--skip-pearson-gate``) the refusal becomes a returned warning (and a ``UserWarning``).
    Returns the warnings.
    """
    weak = {n: correlations.get(n, float("nan")) for n in inputs}
    weak = {n: r for n, r in weak.items() if not (r >= threshold)}
    if not weak:
        return []
    listing = ", ".join(f"r({n}, F_z) = {r:.3f}" for n, r in weak.items())
    better = sorted(
        ((n, r) for n, r in correlations.items() if n not in inputs and r == r), key=lambda p: -p[1]
    )
    hint = f" The best other candidate is {better[0][0]} (r = {better[0][1]:.3f})." if better else ""
    message = (
        f"{source + ': ' if source else ''}{listing}, below the gate of {threshold:.2f} "
        "(paper 000 section 4: "
        "the input-output Pearson correlation must exceed 0.85 before ANFIS training). A map trained on this "
        "data would mostly fit noise. Usual causes on real logs: vibration on the accelerometer (try "
        "--lowpass-hz 1), ground samples (check altitude_m is logged), battery sag with no voltage logged "
        "(the PWM needed for a given thrust drifts during the flight), and a hover-only flight with little "
        f"thrust variation.{hint} Pass --skip-pearson-gate to train anyway (the metrics file records the override)."
    )
    if not force:
        raise CorrelationGateError(message, correlations)
    warnings.warn(message, UserWarning, stacklevel=2)
    return [message]


# --------------------------------------------------------------------------- k of eq. 6
@dataclass(frozen=True)
class MotorSpeedModel:
    """Assumed motor speed: ``Omega = Kv * V * (pwm - pwm_idle) / (pwm_max - pwm_idle)`` [rad/s].

    An ESC maps PWM from idle to full linearly to the duty cycle, and a brushless motor's speed is
    ~ Kv times the applied voltage (no-load; under propeller load it is lower, so k comes out low).
    """

    kv_rpm_per_V: float = bounded(920.0, 10.0, 50_000.0, "rpm/V")  #: DJI E310/2212-class motors of an F450
    battery_V: float = bounded(11.1, 1.0, 100.0, "V")  #: 3S LiPo, nominal
    pwm_idle_us: float = bounded(PWM_IDLE_US, 800.0, 2500.0, "us")
    pwm_max_us: float = bounded(1900.0, 800.0, 2500.0, "us")

    def __post_init__(self) -> None:
        problems = range_problems(self)
        if not problems and not self.pwm_idle_us < self.pwm_max_us:
            problems.append(
                f"pwm_idle_us = {self.pwm_idle_us}, pwm_max_us = {self.pwm_max_us}; "
                "need idle < max"
            )
        if problems:
            raise ThrustDataError("motor speed model: " + "; ".join(problems))

    @property
    def omega_per_us(self) -> float:
        """dOmega/dpwm [rad/s per us] of one motor."""
        return self.kv_rpm_per_V * self.battery_V * RPM_TO_RAD_S / (self.pwm_max_us - self.pwm_idle_us)


@dataclass(frozen=True)
class ThrustConstant:
    """k of eq. 6 from the slope of the trained curve, with the level-based value as a consistency check."""

    k_N_s2: float
    k_from_level_N_s2: float
    mean_slope_N_per_us: float
    hover_omega_rad_s: float
    description: str


def k_thrust_from_curve(amap: AnfisMap, pwm_sum_us: np.ndarray, motor: MotorSpeedModel) -> ThrustConstant:
    """k [N s^2] such that T_i = k Omega_i^2 matches the slope of the trained map (paper 000, Fig. 6).

    Per motor T_i = F(4 pwm_i)/4 (the FMU's convention), so dT_i/dpwm_i = F'(S) at S = 4 pwm_i. With
    Omega_i = K (pwm_i - idle), dT_i/dpwm_i = 2 k K^2 (pwm_i - idle); k is the least-squares fit of that
    line to F'(S) over the training samples ``pwm_sum_us`` (so it weights the flown operating points).
    """
    s = np.asarray(pwm_sum_us, float)
    step_us = 0.5
    slope = (np.asarray(amap.evaluate([s + step_us])) - np.asarray(amap.evaluate([s - step_us]))) / (
        2 * step_us
    )
    excess = s / N_MOTORS - motor.pwm_idle_us
    if np.any(excess <= 0.0):
        raise ThrustDataError(
            f"pwm_idle_us = {motor.pwm_idle_us} is not below every per-motor PWM of the data "
            f"(min {s.min() / N_MOTORS:.0f} us); k cannot be derived"
        )
    K = motor.omega_per_us
    g = 2.0 * K * K * excess
    k = float(np.sum(slope * g) / np.sum(g * g))
    h = (K * excess) ** 2
    level = np.asarray(amap.evaluate([s])) / N_MOTORS
    k_level = float(np.sum(level * h) / np.sum(h * h))
    if not k > 0.0:
        raise ThrustDataError(
            f"the trained curve falls with PWM on average (mean slope {slope.mean():.3g} N/us), so k from "
            f"its slope is {k:.3g} <= 0; give k explicitly (--k-thrust-N-s2)"
        )
    desc = (
        f"slope of the ANFIS curve dF/dS (mean {slope.mean():.4g} N/us) with "
        "Omega = Kv V (pwm - idle)/(max - "
        f"idle), Kv = {motor.kv_rpm_per_V} rpm/V, V = {motor.battery_V} V, idle {motor.pwm_idle_us} us, max "
        f"{motor.pwm_max_us} us; level-based k = {k_level:.3g}"
    )
    return ThrustConstant(k, k_level, float(slope.mean()), float(K * np.median(excess)), desc)
