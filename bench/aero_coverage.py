"""Coverage and width of the 95 % intervals of ``identify aero`` on the demo's synthetic generator.

Each repeat: eight 8 s manoeuvres at 50 Hz from ``identification.flights.synthetic.identification_manoeuvres`` (3-2-1-1
multisteps from trims between 22 and 28 m/s), simulated by a plant whose FIXED parameters differ from the
fitted model's (model mismatch, :data:`MISMATCH`: C_n_p, C_n_delta_a, C_ell_delta_r, C_Y_delta_a, C_L_q,
C_L_alpha, C_m_0, C_D_p, each within its consider std), plus seeded white noise and coloured noise (AR(1),
pole 0.9) per output. Twelve lateral-directional and pitch derivatives are estimated from a start 10 % off
the truth, as ``identify aero`` does: the data bound of ``--bound`` (default "ar", the tool's: the coloured
Cramér-Rao bound with an autoregressive residual model, the segment bootstrap x Student's t only where the
segments scatter more, ``identification.estimation.oem.data_bound``; "bootstrap": the larger of the Bartlett-
tapered bound and the bootstrap x t for every derivative, the tool's before 2026-11-28), the auto-freeing
rounds (``oem.fixed_worth_freeing``, ``oem.FREE_ROUNDS``), plus the consider covariance of every coefficient
still fixed at its prior std (``identification.aero.priors.fixed_sd``). Priors on and off (``--priors``). An
interval covers when |estimate - truth| <= 1.96 printed std.

Printed per parameter and run: bias over scatter, the coverage of the Cramér-Rao bound alone, of the bootstrap
data bound with the equal-segment corrections m/(m-1) and t(m-1), of the data bound, of the printed bound, the
printed bound over the scatter, the median 95 % half-width over the RMS of estimate - truth, and the mean
leverage factor and degrees of freedom of the bootstrap.

Run: ``.venv/bin/python bench/aero_coverage.py [--repeats 50] [--seed 0] [--bound ar] [--priors both]
[--prior-centre model]``.
Target: printed coverage >= 0.90 and median half-width <= 2 x the RMS error (of estimate - truth) for every free
derivative; exit 1 when the repeats show a miss (``replica_verdict``: a point figure past its target within the
Monte Carlo error of the repeats is printed "(unresolved)", not called met).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from identification.aero.priors import CONSIDERED, fixed_sd, geometry_priors
from identification.estimation.oem import (
    BOUNDS,
    FREE_ROUNDS,
    Estimate,
    Manoeuvre,
    OutputErrorEstimator,
    consider_covariance,
    fixed_worth_freeing,
    student_factor,
)
from identification.flights.synthetic import identification_manoeuvres

sys.path.insert(0, str(Path(__file__).resolve().parent))
from replica_verdict import coverage_figure, overall, width_figure

FREE = ["C_ell_p", "C_ell_delta_a", "C_ell_beta", "C_ell_r", "C_n_beta", "C_n_r", "C_n_delta_r", "C_Y_beta",
        "C_Y_delta_r", "C_m_alpha", "C_m_q", "C_m_delta_e"]
OUTPUTS = ["roll_rad", "pitch_rad", "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s",
           "accel_body_y_m_s2", "accel_body_z_m_s2", "airspeed_m_s"]
WHITE = np.array([0.003, 0.003, 0.005, 0.005, 0.005, 0.05, 0.05, 0.1])
COLOURED = WHITE  #: std of the AR(1) component, per output
POLE = 0.9
#: truth = model value * factor (or + offset for parameters at 0) of parameters that stay FIXED in the fit
MISMATCH = {"C_n_p": 1.3, "C_n_delta_a": 1.3, "C_ell_delta_r": 0.7, "C_Y_delta_a": 0.7, "C_L_q": 1.3,
            "C_L_alpha": 0.9, "C_m_0": 1.5, "C_D_p": 0.005}


@dataclass
class Study:
    names: list[str]
    truth: np.ndarray
    values: np.ndarray  #: repeats x free
    crb: np.ndarray
    boot: np.ndarray
    data: np.ndarray  #: max(CR coloured, bootstrap)
    printed: np.ndarray  #: data bound with the consider covariance
    factor: np.ndarray  #: the bootstrap variance's leverage factor (``oem.segment_corrections``)
    dof: np.ndarray  #: its degrees of freedom
    seconds: float
    priors: bool
    segments: int = 8
    bound: str = "ar"

    def scatter(self) -> np.ndarray:
        """The actual scatter of the estimates: root mean square of estimate - truth over the repeats (the
        spread and the bias together: what an interval must cover)."""
        return np.sqrt(np.mean((self.values - self.truth) ** 2, axis=0))

    def width_ratio(self, std: np.ndarray) -> np.ndarray:
        """Median 95 % half-width (1.96 std) over the actual scatter, per parameter."""
        return np.median(1.96 * std, axis=0) / self.scatter()

    def equal_segment_data(self) -> np.ndarray:
        """The data bound with the equal-segment corrections (m/(m-1), Student's t at m-1) in place of the
        leverage factor and the degrees of freedom, on the same fits."""
        m = self.segments
        boot = self.boot / np.sqrt(self.factor) * np.sqrt(m / (m - 1.0)) * student_factor(m - 1.0)
        return np.maximum(self.crb, boot)

    def coverage(self, std: np.ndarray) -> np.ndarray:
        return np.mean(np.abs(self.values - self.truth) <= 1.96 * std, axis=0)


def white_plus_ar1(rng: np.random.Generator, shape: tuple[int, ...], white_sd: object, coloured_sd: object,
                   pole: float = POLE, stationary: bool = False) -> np.ndarray:
    """White noise of std ``white_sd`` plus an AR(1) part (``pole`` per sample, along axis 0) of long-run std
    ``coloured_sd`` (scalars or per-column arrays). The AR(1) part starts, ``stationary``, from a draw of its
    long-run distribution, as a sensor's noise is at any instant of a log (this study's manoeuvres since
    2026-11-30, and the replica's), else from 0 (its std grows to ``coloured_sd`` over the first ~1 / (1 - pole)
    samples: this study's figures in the aero readme before 2026-11-30 were measured so)."""
    white = rng.normal(0.0, 1.0, shape) * white_sd
    drive = rng.normal(0.0, 1.0, shape) * coloured_sd * np.sqrt(1 - pole**2)
    if not stationary:
        return white + lfilter([1.0], [1.0, -pole], drive, axis=0)
    before = rng.normal(0.0, 1.0, (1, *shape[1:])) * coloured_sd  # the AR part one sample before the first
    return white + lfilter([1.0], [1.0, -pole], drive, axis=0, zi=pole * before)[0]


def _noise(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    return white_plus_ar1(rng, shape, WHITE, COLOURED, stationary=True)


def plant_params(model: FixedWingModel, p: np.ndarray) -> np.ndarray:
    """The plant: the model's parameters with :data:`MISMATCH` applied to the fixed ones."""
    out = p.copy()
    for n, f in MISMATCH.items():
        i = model.params.index[n]
        out[i] = out[i] * f if out[i] != 0.0 else f
    return out


def run_study(repeats: int, seed: int = 0, count: int = 8, seconds: float = 8.0, rate: float = 50.0,
              priors: bool = True, bound: str = "ar") -> Study:
    """The Monte Carlo study: ``repeats`` seeded data sets, one estimate each (priors on or off; ``bound`` of
    ``identification.estimation.oem.BOUNDS``, "ar" as ``identify aero``)."""
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    p_plant = plant_params(sim.model, p)
    plant = OutputErrorEstimator(sim.model, p_plant, FREE, OUTPUTS)
    start_values = dict(zip(sim.model.params.index, p, strict=True))
    prior = {n: (v.value, v.sd) for n, v in geometry_priors(start_values).items() if n in FREE} if priors else None
    oe = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, prior=prior, bound=bound)
    truth = p_plant[oe.i_free].copy()
    consider = {n: fixed_sd(n, float(start_values[n])) for n in CONSIDERED if n not in FREE}
    clean = identification_manoeuvres(plant, p_plant, seconds, rate, count, None)
    rows: dict[str, list[np.ndarray]] = {k: [] for k in ("values", "crb", "boot", "data", "printed", "factor", "dof")}
    freed: dict[tuple[str, ...], int] = {}
    t0 = time.perf_counter()
    for k in range(repeats):
        rng = np.random.default_rng(seed + k)
        data = [Manoeuvre(m.x0, m.u, m.y + _noise(rng, m.y.shape), m.dt_s, m.name) for m in clean]
        start = truth * (1 + 0.1 * rng.choice([-1.0, 1.0], size=len(FREE)))
        est = _auto_fit(oe, data, start, consider, prior or {}, freed)
        n = len(FREE)
        rows["values"].append(est.values[:n])
        rows["crb"].append(est.crb_std[:n])
        rows["boot"].append(est.bootstrap_std[:n] if est.bootstrap_std is not None else np.full(n, np.nan))
        rows["data"].append(est.data_std[:n])
        rows["printed"].append(est.std[:n])
        rows["factor"].append(est.bootstrap_factor[:n] if est.bootstrap_factor is not None else np.full(n, np.nan))
        rows["dof"].append(est.bootstrap_dof[:n] if est.bootstrap_dof is not None else np.full(n, np.nan))
    arr = {key: np.array(v) for key, v in rows.items()}
    if freed:
        print("freed by the auto rule (repeats): " + "; ".join(f"{', '.join(c) or 'none'} ({r})"
                                                             for c, r in freed.items()))
    return Study(FREE, truth, arr["values"], arr["crb"], arr["boot"], arr["data"], arr["printed"], arr["factor"],
                 arr["dof"], time.perf_counter() - t0, priors, count, bound)


_ESTIMATORS: dict[tuple[str, ...], OutputErrorEstimator] = {}
#: parameter values the freed coefficients' priors are centred on (None: the fitted model's, as the tool does;
#: ``--prior-centre plant``: the plant's, a diagnostic of whether the priors' pull biases the free derivatives)
PRIOR_CENTRE: np.ndarray | None = None


def _auto_fit(oe: OutputErrorEstimator, data: list[Manoeuvre], start: np.ndarray, consider: dict[str, float],
              prior: dict[str, tuple[float, float]], freed: dict[tuple[str, ...], int]) -> Estimate:
    """What ``identify aero --free auto`` does after its first fit: the consider covariance of the fixed
    coefficients, the ones worth freeing freed (their start value and consider std as prior), a refit from
    the estimate, the consider covariance of the rest; up to ``FREE_ROUNDS`` rounds."""
    est = oe.estimate(data, theta0=start, max_iter=30)
    con = consider_covariance(oe, est, data, consider, compile=True)
    est.consider_cov = con.cov
    chosen: tuple[str, ...] = ()
    for _ in range(FREE_ROUNDS):
        more = tuple(fixed_worth_freeing(est, con))
        if not more:
            break
        chosen += more
        key = (oe.bound, str(PRIOR_CENTRE is None), *chosen)
        centre = oe.p_nominal if PRIOR_CENTRE is None else PRIOR_CENTRE
        if key not in _ESTIMATORS:
            pri = {**prior, **{c: (float(centre[oe.model.params.index[c]]), consider[c]) for c in chosen}}
            _ESTIMATORS[key] = OutputErrorEstimator(oe.model, oe.p_nominal, [*oe.free, *chosen], oe.outputs,
                                                    prior=pri, bound=oe.bound)
        big = _ESTIMATORS[key]
        theta0 = np.concatenate([est.values[:est.n_global], big.p_nominal[big.i_free[est.n_global:]]])
        est = big.estimate(data, theta0=theta0, max_iter=30)
        con = consider_covariance(big, est, data, consider, compile=True)
        est.consider_cov = con.cov
    freed[chosen] = freed.get(chosen, 0) + 1
    return est


#: the target: coverage of the printed 95 % intervals at least this ...
MIN_COVERAGE = 0.90
#: ... and their median half-width at most this many times the actual scatter (RMS of estimate - truth)
MAX_WIDTH = 2.0


def report(st: Study) -> str:
    """Print the table of one study; returns its verdict on the printed bound ("met", "miss", "unresolved":
    ``replica_verdict``, from the coverage and the median half-width over the RMS of estimate - truth)."""
    r = len(st.values)
    scatter = np.std(st.values - st.truth, axis=0, ddof=1) if r > 1 else np.full(len(FREE), np.nan)
    cov_crb, cov_data, cov_pr = st.coverage(st.crb), st.coverage(st.data), st.coverage(st.printed)
    cov_eq = st.coverage(st.equal_segment_data())
    width = st.width_ratio(st.printed)
    # the AR bound and the raw bootstrap without Student's factor, with the consider share: a candidate, not the tool's
    no_t = np.hypot(np.fmax(st.crb, np.nan_to_num(st.boot)), np.sqrt(np.maximum(st.printed ** 2 - st.data ** 2, 0.0)))
    cov_no_t, width_no_t = st.coverage(no_t), st.width_ratio(no_t)
    print(f"priors {'ON (geometry, MAP)' if st.priors else 'OFF'}, bound {st.bound!r}: {r} repeats in "
          f"{st.seconds:.0f} s; coverage of the 95 % intervals (target >= {MIN_COVERAGE:.2f}); 'data m-1': the "
          "bootstrap data bound with the equal-segment m/(m-1) and t(m-1) in place of its leverage factor and "
          "degrees of freedom (mean of each shown); 'hw/sd': median 95 % half-width of the printed bound over the "
          "scatter (std of estimate - truth); 'no t': max(CR, bootstrap) without Student's factor, "
          "plus the consider share (a candidate bound, not the tool's); the verdict columns: the printed bound's "
          f"coverage and median half-width over the RMS of estimate - truth (target <= {MAX_WIDTH:g}), each with "
          "its one-sided 95 % Monte Carlo bound towards the target")
    print(f"{'parameter':<14} {'truth':>9} {'bias/sd':>8} {'CR col':>7} {'data m-1':>9} {'data':>7} {'printed':>8} "
          f"{'printed/sd':>11} {'hw/sd':>7} {'factor':>7} {'dof':>5} {'no t':>5} {'hw/sd':>7}  "
          f"{'coverage [upper]':<22} hw/rms [lower]")
    figures = []
    for i, n in enumerate(FREE):
        bias = (np.mean(st.values[:, i]) - st.truth[i]) / scatter[i]
        err = st.values[:, i] - st.truth[i]
        hw = 1.96 * st.printed[:, i]
        cov, w = coverage_figure(np.abs(err) <= hw, MIN_COVERAGE), width_figure(hw, err, MAX_WIDTH, stat="rms")
        figures += [cov, w]
        print(f"{n:<14} {st.truth[i]:9.4f} {bias:8.2f} {cov_crb[i]:7.2f} {cov_eq[i]:9.2f} {cov_data[i]:7.2f} "
              f"{cov_pr[i]:8.2f} {np.mean(st.printed[:, i]) / scatter[i]:11.2f} {width[i]:7.2f} "
              f"{np.mean(st.factor[:, i]):7.2f} {np.mean(st.dof[:, i]):5.1f} {cov_no_t[i]:5.2f} {width_no_t[i]:7.2f}  "
              f"{cov.text():<22} {w.text()}")
    verdict = overall(figures)
    print(f"printed bound ({st.bound}) + consider covariance of the fixed coefficients; worst coverage "
          f"{float(np.min(cov_pr)):.2f}, largest half-width / scatter {float(np.max(width)):.2f} -> "
          + {"met": "PASS", "miss": "FAIL (the repeats show a miss)",
             "unresolved": "NO MISS SHOWN (figures marked (unresolved) are past their targets by less than the "
                           f"Monte Carlo error of {r} repeats; not a pass)"}[verdict] + "\n")
    return verdict


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--bound", choices=BOUNDS, default="ar", help="the data bound (identify aero's: ar)")
    parser.add_argument("--priors", choices=("both", "on", "off"), default="both")
    parser.add_argument("--prior-centre", choices=("model", "plant"), default="model",
                        help="centre of the freed coefficients' priors: the fitted model's value (the tool's) or the "
                             "plant's (a diagnostic)")
    args = parser.parse_args()
    if args.prior_centre == "plant":
        global PRIOR_CENTRE
        sim = Simulator(FixedWingModel())
        PRIOR_CENTRE = plant_params(sim.model, sim.params(density_altitude_scaling=0.0))
    if not 1 <= args.repeats <= 1000:
        parser.error("--repeats must be in 1..1000")
    runs = {"both": (True, False), "on": (True,), "off": (False,)}[args.priors]
    got = [report(run_study(args.repeats, args.seed, priors=on, bound=args.bound)) for on in runs]
    print("; ".join(f"priors {'on' if on else 'off'}: {v}" for on, v in zip(runs, got, strict=True))
          + f" (targets: coverage >= {MIN_COVERAGE:.2f}, median half-width <= {MAX_WIDTH:g} x the RMS error)")
    return 1 if "miss" in got else 0

if __name__ == "__main__":
    raise SystemExit(main())
