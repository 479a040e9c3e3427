"""Study: do motor dynamics, the PWM/IMU delay or voltage sag under load explain the PX4 thrust error?

Leave-one-flight-out on the two shared PX4 flights (and the delay-free check on the three Erle flights), with
the one-rule map ``T = a sum (u V/V_nom)^2 + b sum u V/V_nom`` (PX4) or ``a sum u^2 + b sum u`` (Erle) fitted by
least squares on the training flight(s). For each accelerometer delay ``d`` (fixed, instead of the per-flight
estimate of ``build_thrust_dataset``) and motor time constant ``tau`` (first-order lag of each motor's features,
which for a one-rule map equals the FMU's ``tau_motor_s`` lag on the thrust), prints the held-out pooled RMSE,
raw and with the per-flight hover calibration (hover = |climb| < 0.3 m/s, no tilt correction, so Erle
calibrated figures differ slightly from ``identify thrust``), and the in-sample RMSE of each fold. Then the same
map with the battery voltage replaced by an estimate of the instantaneous terminal voltage ``V_oc - R I_hat`` (``R`` and
``V_oc`` from the 2 Hz voltage/current, ``I_hat = k sum u^3`` at the PWM rate). Then the common-mode vs
differential curvature split of the one-rule voltage map (:func:`mode_split`), then other physical forms of it
(:func:`other_forms`: asymmetric motor lag, voltage exponent, hover battery state on top of the voltage). Then
how far static per-motor maps fitted on the held-out flight itself get (:func:`static_floor`) and whether
a fitted filter or an interpolated command transfers between the flights (:func:`filters_and_alignment`). Last,
per PX4 flight held out, the
coherence between the model's thrust (fitted on the other flight) and the measured thrust by frequency band,
with the transfer function ``H = S_xy / S_xx`` and the error no linear time-invariant map of the model's thrust
(lag, delay, any filter) can remove: ``sqrt(int (1 - coh) S_yy df)``. A study, not a target: exit 0 when the
data are there, 2 when not.

    .venv/bin/python bench/thrust_dynamics_study.py
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy import signal

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.common.units import G0_M_S2 as G0
from identification.logs.readers import read_log
from identification.thrust.battery import HOVER_TAUS_S, hover_thrust_scale
from identification.thrust.dataset import ThrustDatasetConfig, build_thrust_dataset
from identification.thrust.model import FlightData, ModelSpec, command, hover_scale, poly_features
from identification.thrust.workflow import HOVER_CLIMB_M_S

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
PX4 = ((DATA / "quadrotor_px4_csv" / "drone1-8", 1.32), (DATA / "quadrotor_px4_csv" / "drone1-10", 1.085))
ERLE = tuple((DATA / "quadrotor" / f"arducopter_x_quad_real_{n}.BIN", 1.14) for n in (218, 104, 105))
IDLE_US, FULL_US = 1000.0, 2000.0
#: the thrust identification's target: the model's pooled RMSE at most this times the best baseline's
TARGET_RATIO = 0.95
DELAYS_S = (0.0, 0.01, 0.02, 0.03, 0.04)
TAUS_S = (0.0, 0.01, 0.02, 0.03, 0.05)


def flight(path: Path, mass_kg: float, delay_s: float | None) -> tuple[FlightData, object]:
    """Airborne samples of one log at a fixed accelerometer delay (None: the per-flight estimate)."""
    log = read_log(path)
    ds = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=mass_kg, airborne_on_mean_pwm=True, lag_s=delay_s))
    pwm = np.stack([ds.inputs[f"motor_{k}_pwm_us"] for k in range(1, 5)], axis=1)
    climb = ds.inputs.get("climb_rate_m_s")
    hover = np.abs(climb) < HOVER_CLIMB_M_S if climb is not None else np.ones(ds.n_samples, bool)
    f = FlightData(path.name, pwm, ds.inputs.get("battery_voltage_V"), hover, ds.time_s, ds.fz_N, mass_kg * G0,
                   ds.sample_period_s)
    return f, log


def gap_free(f: FlightData) -> list[tuple[int, int]]:
    """Index ranges ``[lo, hi)`` of ``f`` between log gaps (where a lag restarts)."""
    starts = np.flatnonzero(np.diff(f.time_s, prepend=-np.inf) > 1.5 * f.period_s)
    return list(zip(starts.tolist(), [*starts[1:].tolist(), len(f.time_s)], strict=True))


def nominal_V(volts: list[np.ndarray]) -> float:
    """The nominal voltage [V] of ``identify thrust``: the median over all flights."""
    return float(np.median(np.concatenate(volts)))


def lagged(x: np.ndarray, f: FlightData, tau_s: float) -> np.ndarray:
    """First-order lag (time constant ``tau_s``) of ``x`` sampled on ``f``, restarted at each log gap."""
    if tau_s <= 0.0:
        return x
    a = 1.0 - np.exp(-f.period_s / tau_s)
    out = np.empty_like(x)
    for lo, hi in gap_free(f):
        seg = x[lo:hi]
        out[lo:hi] = signal.lfilter([a], [1.0, a - 1.0], seg, zi=[seg[0] * (1.0 - a)])[0]
    return out


def features(f: FlightData, ratio: np.ndarray | None, tau_s: float) -> np.ndarray:
    """Summed ``u^2`` and ``u`` (``u`` times the battery ratio ``V/V_nom`` when given), lagged by ``tau_s``."""
    u = command(f.pwm_us, IDLE_US, FULL_US)
    if ratio is not None:
        u = u * ratio[:, None]
    return np.stack([lagged((u * u).sum(axis=1), f, tau_s), lagged(u.sum(axis=1), f, tau_s)], axis=1)


def quad(x: np.ndarray) -> np.ndarray:
    """The one-rule map's regressors ``sum x^2, sum x`` of a per-motor input (N, 4)."""
    return np.stack([(x * x).sum(axis=1), x.sum(axis=1)], axis=1)


def u_eff(f: FlightData, nominal: float) -> np.ndarray:
    """Per-motor ``u V/V_nom`` (N, 4) of a flight with a voltage log."""
    return command(f.pwm_us, IDLE_US, FULL_US) * (f.volt_V / nominal)[:, None]  # type: ignore[operator]


def voltage_poly(f: FlightData, nominal: float) -> np.ndarray:
    """Regressors of ``identify thrust``'s voltage baseline ``sum u^2, sum u, sum u^2 V/V_nom``."""
    return poly_features(f, ModelSpec(IDLE_US, FULL_US, nominal, True), True)


def lofo(flights: list[FlightData], volts: list[np.ndarray | None], tau_s: float) -> tuple[float, float, list[float]]:
    """Held-out pooled RMSE [N] raw and hover-calibrated, and the in-sample RMSE of each fold (voltage [V] per
    flight, or None; nominal voltage: the median over all flights, as ``identify thrust``)."""
    ratio = {id(f): None for f in flights}
    if volts[0] is not None:
        nominal = nominal_V(volts)  # type: ignore[arg-type]
        ratio = {id(f): v / nominal for f, v in zip(flights, volts, strict=True)}  # type: ignore[operator]
    got = lofo_with(flights, lambda f: features(f, ratio[id(f)], tau_s))
    return got.raw, got.cal, got.inside


def mode_split(flights: list[FlightData], volts: list[np.ndarray]) -> None:
    """Common-mode vs differential curvature: ``T = A n xbar^2 + D sum (x_i - xbar)^2 + B sum x_i`` with ``x`` the
    per-motor ``u V/V_nom`` and ``xbar`` their mean (the one-rule map has ``A = D``). Prints the held-out pooled
    RMSE raw / calibrated, the coefficients of each fold, and the slope of the total thrust in one motor's
    command at the band corner (that motor at the band's low end, the others at its top): ``2 A xbar + B +
    2 D (x_k - xbar)``; a negative slope means the total thrust falls as that motor's command rises."""
    nominal = nominal_V(volts)
    xs = {id(f): command(f.pwm_us, IDLE_US, FULL_US) * (v / nominal)[:, None]
          for f, v in zip(flights, volts, strict=True)}

    def design(f: FlightData) -> np.ndarray:
        x = xs[id(f)]
        xbar = x.mean(axis=1, keepdims=True)
        return np.stack([x.shape[1] * xbar[:, 0] ** 2, ((x - xbar) ** 2).sum(axis=1), x.sum(axis=1)], axis=1)

    got = lofo_with(flights, design)
    for test, (a, d, b) in zip(flights, got.thetas, strict=True):
        lo, hi = float(xs[id(test)].min()), float(xs[id(test)].max())
        xbar = (lo + 3.0 * hi) / 4.0
        corner = 2 * a * xbar + b + 2 * d * (lo - xbar)
        print(f"  fold without {test.name}: A {a:.2f} N, D {d:.2f} N, B {b:.2f} N; total-thrust slope at the corner "
              f"{corner:+.2f} N per unit command")
    print(f"  held-out {got.raw:.3f} / {got.cal:.3f}")


def asymmetric_lag(x: np.ndarray, f: FlightData, up_s: float, down_s: float) -> np.ndarray:
    """Per-motor first-order lag of ``x`` (N, 4) with a spin-up and a spin-down time constant [s] (a motor
    without active braking slows down more slowly than it speeds up); 0 passes through."""
    a_up = 1.0 - np.exp(-f.period_s / up_s) if up_s > 0 else 1.0
    a_dn = 1.0 - np.exp(-f.period_s / down_s) if down_s > 0 else 1.0
    out = np.empty_like(x)
    for lo, hi in gap_free(f):
        state = x[lo].copy()
        out[lo] = state
        for k in range(lo + 1, hi):  # a few thousand samples
            d = x[k] - state
            state = state + np.where(d > 0, a_up, a_dn) * d
            out[k] = state
    return out


@dataclass
class Lofo:
    """Held-out pooled RMSE [N] raw and calibrated, each fold's coefficients and in-sample RMSE [N]."""

    raw: float
    cal: float
    thetas: list[np.ndarray]
    inside: list[float]


def lofo_with(flights: list[FlightData], design: Callable[[FlightData], np.ndarray],
              state_tau_s: float | None = None) -> Lofo:
    """Leave-one-flight-out of the least-squares map ``design(f) @ theta`` fitted on the other flights, scored
    raw and with the per-flight hover calibration (``identification.thrust.model.hover_scale``); with
    ``state_tau_s`` the prediction is scaled by the hover-condition battery state
    (``identification.thrust.battery.hover_thrust_scale``), which is then its own calibration."""
    sse = sse_cal = 0.0
    n = 0
    thetas, inside = [], []
    for i, test in enumerate(flights):
        tr = [f for j, f in enumerate(flights) if j != i]
        a, y = np.concatenate([design(f) for f in tr]), np.concatenate([f.thrust_N for f in tr])
        theta = np.linalg.lstsq(a, y, rcond=None)[0]
        thetas.append(theta)
        inside.append(float(np.sqrt(np.mean((a @ theta - y) ** 2))))
        pred = design(test) @ theta
        if state_tau_s is None:
            cal = pred * hover_scale(pred, test)
        else:
            pred = cal = pred * hover_thrust_scale(test.time_s, pred, test.hover, test.weight_N, state_tau_s)
        sse += float(np.sum((pred - test.thrust_N) ** 2))
        sse_cal += float(np.sum((cal - test.thrust_N) ** 2))
        n += len(pred)
    return Lofo(float(np.sqrt(sse / n)), float(np.sqrt(sse_cal / n)), thetas, inside)


def other_forms(flights: list[FlightData]) -> None:
    """Three more physical forms of the one-rule ``u_eff`` map on PX4 (per-flight delay): an asymmetric motor
    lag, the voltage exponent ``x = u (V/V_nom)^g`` (motor speed ~ duty x voltage is ``g = 1``), and a hover
    battery state on top of the logged voltage."""
    nominal = nominal_V([f.volt_V for f in flights])  # type: ignore[misc]

    def x_of(f: FlightData, g: float = 1.0) -> np.ndarray:
        return command(f.pwm_us, IDLE_US, FULL_US) * ((f.volt_V / nominal) ** g)[:, None]  # type: ignore[operator]

    for up, down in ((0.0, 0.0), (0.0, 0.02), (0.0, 0.04), (0.0, 0.08), (0.02, 0.02), (0.02, 0.04)):
        got = lofo_with(flights, lambda f, up=up, down=down: quad(asymmetric_lag(x_of(f), f, up, down)))
        raw, cal = got.raw, got.cal
        print(f"  motor lag up {up * 1e3:2.0f} ms, down {down * 1e3:2.0f} ms: {raw:.3f} / {cal:.3f}")
    for g in (0.0, 0.5, 1.0, 1.5, 2.0):
        got = lofo_with(flights, lambda f, g=g: quad(x_of(f, g)))
        raw, cal = got.raw, got.cal
        print(f"  voltage exponent {g:.1f}: {raw:.3f} / {cal:.3f}")
    for tau in HOVER_TAUS_S:
        raw = lofo_with(flights, lambda f: quad(x_of(f)), state_tau_s=tau).raw
        print(f"  hover battery state tau {tau:.0f} s on top of the voltage: {raw:.3f} (its own calibration)")


def knots_design(x: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Per-motor piecewise-linear map of ``x`` (N, 4) through zero, summed over the motors: ``sum x_i`` and
    ``sum max(x_i - k, 0)`` per knot (any static per-motor shape on the band, monotone or not)."""
    return np.stack([x.sum(axis=1), *(np.maximum(x - k, 0.0).sum(axis=1) for k in knots)], axis=1)


def static_floor(flights: list[FlightData]) -> None:
    """Pooled calibrated RMSE [N] of static per-motor maps fitted on each held-out flight itself (in-sample: a
    floor for any map of the family fitted on the other flight; the target ``TARGET_RATIO x`` the held-out
    calibrated voltage polynomial, the ``identify thrust`` baseline ``sum u^2, sum u, sum u^2 V``, is printed
    before); then the most flexible of them, piecewise-linear per motor, fitted on the other flight
    (leave-one-flight-out)."""
    nominal = nominal_V([f.volt_V for f in flights])  # type: ignore[misc]

    def vpoly(f: FlightData) -> np.ndarray:
        return voltage_poly(f, nominal)

    def ueff(f: FlightData) -> np.ndarray:
        return quad(u_eff(f, nominal))

    def knots(f: FlightData, n_knots: int = 9) -> np.ndarray:
        return knots_design(u_eff(f, nominal), np.linspace(0.1, 0.9, n_knots))

    for name, design in (("voltage polynomial sum u^2, sum u, sum u^2 V", vpoly), ("one-rule u_eff map", ueff),
                         ("per-motor piecewise-linear x = u V/V_nom, 9 knots", knots)):
        sse, n = 0.0, 0
        for f in flights:
            a = design(f)
            pred = a @ np.linalg.lstsq(a, f.thrust_N, rcond=None)[0]
            sse += float(np.sum((pred * hover_scale(pred, f) - f.thrust_N) ** 2))
            n += len(pred)
        print(f"  {name}, fitted on the held-out flight itself: {np.sqrt(sse / n):.3f} calibrated")
    for n_knots in (5, 9):
        got = lofo_with(flights, lambda f, n_knots=n_knots: knots(f, n_knots))
        print(f"  per-motor piecewise-linear, {n_knots} knots, fitted on the other flight: raw / calibrated "
              f"{got.raw:.3f} / {got.cal:.3f}")


def shifted(a: np.ndarray, f: FlightData, k: int) -> np.ndarray:
    """``a`` (N, m) moved ``k`` samples later (``k`` < 0: earlier) within each gap-free segment, edges held."""
    out = a.copy()
    for lo, hi in gap_free(f):
        if hi - lo <= abs(k):
            continue
        if k > 0:
            out[lo + k:hi], out[lo:lo + k] = a[lo:hi - k], a[lo]
        elif k < 0:
            out[lo:hi + k], out[hi + k:hi] = a[lo - k:hi], a[hi - 1]
    return out


def filters_and_alignment(flights_of: Callable[[float | None], list[FlightData]]) -> None:
    """Leave-one-flight-out of the one-rule ``u_eff`` map with its features filtered by a fitted FIR (taps at
    the listed sample lags; negative = later PWM samples, not causal), at the per-flight delay estimate and at
    0 ms; then with every predictor's command interpolated halfway to the next PWM sample (the mean over the
    sample interval if the PWM moved linearly), scored beside the voltage polynomial on the same commands."""
    for delay in (None, 0.0):
        fl = flights_of(delay)
        nominal = nominal_V([f.volt_V for f in fl])  # type: ignore[misc]
        for lags in ((0,), (0, 1, 2), tuple(range(8)), (-1, 0, 1)):
            def design(f: FlightData, lags: tuple[int, ...] = lags, nominal: float = nominal) -> np.ndarray:
                base = features(f, f.volt_V / nominal, 0.0)  # type: ignore[operator]
                return np.concatenate([shifted(base, f, k) for k in lags], axis=1)
            got = lofo_with(fl, design)
            d = "per-flight delay" if delay is None else f"delay {delay * 1e3:.0f} ms"
            print(f"  {d:<16} FIR taps {lags}: {got.raw:.3f} / {got.cal:.3f}")
    fl = flights_of(None)
    nominal = nominal_V([f.volt_V for f in fl])  # type: ignore[misc]
    for w in (0.0, 0.5):
        moved = {id(f): replace(f, pwm_us=(1.0 - w) * f.pwm_us + w * shifted(f.pwm_us, f, -1)) for f in fl}

        def ueff(f: FlightData, moved: dict[int, FlightData] = moved) -> np.ndarray:
            return quad(u_eff(moved[id(f)], nominal))

        def vpoly(f: FlightData, moved: dict[int, FlightData] = moved) -> np.ndarray:
            return voltage_poly(moved[id(f)], nominal)

        m, b = lofo_with(fl, ueff), lofo_with(fl, vpoly)
        print(f"  command {w:.1f} of the way to the next PWM sample: map {m.raw:.3f} / {m.cal:.3f}, voltage "
              f"polynomial {b.raw:.3f} / {b.cal:.3f}, calibrated ratio {m.cal / b.cal:.3f}")


def terminal_voltage(f: FlightData, log: object) -> tuple[np.ndarray, float]:
    """``V_oc - R I_hat`` [V] at the PWM samples and ``R`` [ohm]: ``V = c0 + c1 t - R I`` on the 2 Hz samples."""
    sig = log.signals  # type: ignore[attr-defined]
    t_i, i_a = np.asarray(sig["battery_current_a"].t_s), np.asarray(sig["battery_current_a"].values, float)
    t_v, v = np.asarray(sig["battery_voltage_v"].t_s), np.asarray(sig["battery_voltage_v"].values, float)
    power = (command(f.pwm_us, IDLE_US, FULL_US) ** 3).sum(axis=1)
    ok = (t_i > f.time_s[0]) & (t_i < f.time_s[-1])
    t, i_a = t_i[ok], i_a[ok]
    v_i = np.interp(t, t_v, v)
    c = np.linalg.lstsq(np.stack([np.ones_like(t), t - t[0], i_a], axis=1), v_i, rcond=None)[0]
    k = np.linalg.lstsq(np.interp(t, f.time_s, power)[:, None], i_a, rcond=None)[0][0]
    return np.interp(f.time_s, t, v_i - c[2] * i_a) + c[2] * k * power, float(-c[2])


BANDS_HZ = ((0.0, 1.0), (1.0, 2.0), (2.0, 3.0), (3.0, 6.0), (6.0, 12.0), (12.0, 25.0))
SEGMENT_N = 64  #: Welch segment length [samples] (about 1.4 s at 46 Hz); shorter log segments are skipped


def spectra(x: np.ndarray, y: np.ndarray, f: FlightData) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies [Hz], cross and auto spectra (S_xy, S_xx, S_yy) averaged over the gap-free segments."""
    starts = np.flatnonzero(np.diff(f.time_s, prepend=-np.inf) > 1.5 * f.period_s)
    acc: list[np.ndarray] = [np.zeros(SEGMENT_N // 2 + 1, complex), np.zeros(SEGMENT_N // 2 + 1),
                             np.zeros(SEGMENT_N // 2 + 1)]
    used = 0
    freq = np.zeros(0)
    for lo, hi in zip(starts, [*starts[1:], len(x)], strict=True):
        if hi - lo < SEGMENT_N:
            continue
        a, b = x[lo:hi] - x[lo:hi].mean(), y[lo:hi] - y[lo:hi].mean()
        freq, sxy = signal.csd(a, b, fs=1.0 / f.period_s, nperseg=SEGMENT_N)
        for k, s_k in enumerate((sxy, signal.welch(a, fs=1.0 / f.period_s, nperseg=SEGMENT_N)[1],
                                 signal.welch(b, fs=1.0 / f.period_s, nperseg=SEGMENT_N)[1])):
            acc[k] = acc[k] + (hi - lo) * s_k
        used += hi - lo
    return freq, acc[0] / used, acc[1].real / used, acc[2].real / used


def coherence_floor(flights: list[FlightData]) -> None:
    """Print, per held-out flight, coherence / transfer function / LTI-irreducible error by band."""
    nominal = nominal_V([f.volt_V for f in flights])  # type: ignore[arg-type]
    for i, test in enumerate(flights):
        tr = flights[1 - i]
        theta = np.linalg.lstsq(features(tr, tr.volt_V / nominal, 0.0), tr.thrust_N, rcond=None)[0]
        pred = features(test, test.volt_V / nominal, 0.0) @ theta
        freq, sxy, sxx, syy = spectra(pred, test.thrust_N, test)
        coh = np.abs(sxy) ** 2 / (sxx * syy)
        df = freq[1] - freq[0]
        rmse = float(np.sqrt(np.mean((pred - test.thrust_N) ** 2)))
        print(f"  {test.name}: model RMSE {rmse:.3f} N (all samples); over gap-free segments >= {SEGMENT_N} samples, "
              "the error no LTI map of the model's thrust removes "
              f"{np.sqrt(np.sum((1 - coh) * syy) * df):.3f} N")
        for lo, hi in BANDS_HZ:
            m = (freq >= lo) & (freq < hi)
            h = sxy[m] / sxx[m]
            floor = np.sqrt(np.sum(((1 - coh) * syy)[m]) * df)
            print(f"    {lo:4.1f}-{hi:4.1f} Hz: coherence {coh[m].mean():.2f}, |H| {np.abs(h).mean():.2f}, "
                  f"phase {np.degrees(np.angle(h)).mean():+4.0f} deg, irreducible {floor:.3f} N"
                  f" of {np.sqrt(np.sum(syy[m]) * df):.3f} N")


def main() -> int:
    if not all(p.exists() for p, _ in (*PX4, *ERLE)):
        print(f"bench/thrust_dynamics_study.py: needs {DATA}")
        return 2
    print("PX4 LOFO, one-rule voltage map: held-out pooled RMSE [N] raw / calibrated; in-sample RMSE per fold")
    for delay in (None, *DELAYS_S):
        loaded = [flight(p, m, delay) for p, m in PX4]
        fl = [f for f, _ in loaded]
        for tau in TAUS_S if delay is not None else (0.0,):
            raw, cal, inside = lofo(fl, [f.volt_V for f in fl], tau)
            d = "per-flight estimate" if delay is None else f"{delay * 1e3:.0f} ms"
            print(f"  delay {d:<19} tau {tau * 1e3:3.0f} ms: {raw:.3f} / {cal:.3f}   in-sample "
                  + " ".join(f"{x:.3f}" for x in inside))
    loaded = [flight(p, m, None) for p, m in PX4]
    sag = [terminal_voltage(f, log) for f, log in loaded]
    fl = [f for f, _ in loaded]
    raw, cal, _ = lofo(fl, [v for v, _ in sag], 0.0)
    print(f"  V_oc - R I_hat (R = {', '.join(f'{r * 1e3:.1f}' for _, r in sag)} mOhm): {raw:.3f} / {cal:.3f}")
    print("PX4 common-mode vs differential curvature (u V/V_nom; one-rule map: A = D)")
    mode_split(fl, [f.volt_V for f in fl])  # type: ignore[misc]
    nominal = nominal_V([f.volt_V for f in fl])  # type: ignore[misc]
    baseline = lofo_with(fl, lambda f: voltage_poly(f, nominal)).cal
    target = TARGET_RATIO * baseline
    print(f"PX4 calibrated target in this study's calibration (no tilt): {TARGET_RATIO} x the held-out voltage "
          f"polynomial {baseline:.3f} = {target:.3f}")
    print(f"PX4 other physical forms of the one-rule u_eff map (calibrated target {target:.3f})")
    other_forms(fl)
    print(f"PX4 floor of static per-motor maps (calibrated pooled RMSE [N]; target {target:.3f})")
    static_floor(fl)
    print("PX4 fitted filters and command interpolation, LOFO raw / calibrated")
    filters_and_alignment(lambda delay: [flight(p, m, delay)[0] for p, m in PX4])
    print("PX4 coherence of the held-out measured thrust with the model's (per-flight delay estimate)")
    coherence_floor(fl)
    print("Erle LOFO, one-rule map (no voltage), per-flight delay estimate")
    erle = [flight(p, m, None)[0] for p, m in ERLE]
    for tau in TAUS_S:
        raw, cal, inside = lofo(erle, [None] * len(erle), tau)
        print(f"  tau {tau * 1e3:3.0f} ms: {raw:.3f} / {cal:.3f}   in-sample " + " ".join(f"{x:.3f}" for x in inside))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
