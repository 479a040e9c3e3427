"""Self-contained HTML validation reports (plots embedded as PNG data URIs) and the batch index page."""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.ticker import MaxNLocator, NullLocator

from identification.common import plots
from identification.validation.replay import ReplayResult

STYLE = ("body{font-family:sans-serif;margin:2em;max-width:1100px}table{border-collapse:collapse;margin:1em 0}"
         "td,th{border:1px solid #bbb;padding:3px 8px;font-size:90%;text-align:right}th{background:#eee}"
         "td:first-child{text-align:left}.fail{color:#b00;font-weight:bold}.pass{color:#070}img{max-width:100%}")


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    # fast zlib level: the default level 6 costs more than drawing the figure, for a few percent of size
    fig.savefig(buf, format="png", dpi=REPORT_DPI, pil_kwargs={"compress_level": 1})
    plots.plt.close(fig)
    return f"<img src='data:image/png;base64,{base64.b64encode(buf.getvalue()).decode()}'/>"


def _table(header: Sequence[str], rows: Sequence[Sequence[str]], raw: bool = False) -> str:
    esc = (lambda s: s) if raw else html.escape
    out = ["<table><tr>", *(f"<th>{html.escape(h)}</th>" for h in header), "</tr>"]
    for r in rows:
        out.append("<tr>" + "".join(f"<td>{esc(str(c))}</td>" for c in r) + "</tr>")
    out.append("</table>")
    return "".join(out)


#: most samples drawn per series: a 300 s log at 100 Hz has 30000; beyond a few thousand a PNG shows no more
MAX_PLOT_POINTS = 1500
REPORT_DPI = 72


def _label(ax: Any, text: str) -> None:
    """A title placed by hand: ``set_title`` measures every tick label to dodge them, 40 ms an axes."""
    ax.text(0.0, 1.02, text, transform=ax.transAxes, fontsize=8, ha="left", va="bottom")


def _signal_figures(res: ReplayResult) -> list[str]:
    """All signals in one figure: one row per signal (log and FMU overlaid), then one strip chart of every
    residual divided by its signal's standard deviation, rows offset; and paper 000's Fig. 5.

    One figure with one axes per signal: matplotlib's cost is mostly per axes (ticks, text), so residuals share
    a single strip-chart axes rather than one axes each.
    """
    parts = []
    edges = [w[0] for w in res.windows[1:]]
    k = max(1, len(res.t_s) // MAX_PLOT_POINTS)
    t = res.t_s[::k]
    n = len(res.maps)
    height = 1.4 + 1.5 * n + 0.45 * n
    fig, axes = plots.figure(n + 1, 1, sharex=False, squeeze=False, figsize=(10.0, height), layout=None,
                             height_ratios=[1.5] * n + [0.45 * n])
    fig.subplots_adjust(left=0.12, right=0.99, top=1 - 0.3 / height, bottom=0.5 / height, hspace=0.45)
    strip = axes[-1, 0]
    for row, (ax, m) in enumerate(zip(axes[:-1, 0], res.maps, strict=True)):
        meas, mod = res.measured[m.fmu], res.model[m.fmu]
        if res.bands is not None and m.fmu in res.bands.lo:
            ax.fill_between(t, res.bands.lo[m.fmu][::k], res.bands.hi[m.fmu][::k], color="tab:red", alpha=0.2, lw=0,
                            label=f"FMU 5-95 % ({res.bands.info['draws']} draws)")
        ax.plot(t, meas[::k], color="0.25", lw=0.9, label="log")
        ax.plot(t, mod[::k], color="tab:red", lw=0.9, label="FMU")
        if m.fmu in res.persistence:
            ax.plot(t, res.persistence[m.fmu][::k], color="tab:green", lw=0.7, ls="--", label="persistence")
        if edges:  # window starts, one collection (an axvline each costs ms per window)
            ax.vlines(edges, 0, 1, transform=ax.get_xaxis_transform(), color="tab:blue", lw=0.4, alpha=0.3)
        sc = res.scores[m.fmu]
        _label(ax, f"FMU {m.fmu} against log {m.log}{' (wrapped angle, shown unwrapped)' if m.wrap else ''}: "
                   f"{sc.verdict}, skill vs persistence {sc.skill_persistence:+.2f}, Theil U {sc.fit.theil_u:.3f}, "
                   f"RMSE {sc.fit.rmse:.3g}"
                   + (f", band coverage {res.bands.coverage[m.fmu]:.0%}" if res.bands is not None else ""))
        ax.set_xlim(t[0], t[-1])
        if row == 0:
            ax.legend(loc="upper right", fontsize=7)
        scale = float(np.nanstd(meas)) or 1.0
        strip.plot(t, (meas - mod)[::k] / scale - 4.0 * row, lw=0.6)
    strip.set_yticks([-4.0 * r for r in range(n)], [m.fmu for m in res.maps], fontsize=7)
    strip.set_ylim(-4.0 * n + 2.0, 2.0)  # +-2 std per row; larger excursions are clipped at the frame
    for ax in axes[:-1, 0]:
        ax.yaxis.set_major_locator(MaxNLocator(3))
        ax.xaxis.set_major_locator(NullLocator())  # the strip chart below carries the time axis
    strip.xaxis.set_major_locator(MaxNLocator(8))
    strip.set_xlim(t[0], t[-1])
    _label(strip, "residuals (log - FMU) / std of the log signal, one row per signal (4 units apart)")
    strip.set_xlabel("log time [s]")
    parts.append(_png(fig))
    if "thrust_total_N" in res.measured:  # paper 000 Fig. 5: modelled thrust against the measured force
        meas, mod = res.measured["thrust_total_N"], res.model["thrust_total_N"]
        parts.append("<h3>Thrust map against the measured force F_z = -m a_z (paper 000 Fig. 5)</h3>")
        fig, ax = plots.figure(figsize=(5.0, 4.5), layout=None)
        fig.subplots_adjust(left=0.14, right=0.97, top=0.92, bottom=0.12)
        ax.plot(meas[::k], mod[::k], ".", ms=2, alpha=0.4)
        lim = [float(np.nanmin([meas, mod])), float(np.nanmax([meas, mod]))]
        ax.plot(lim, lim, "k--", lw=1, label="ideal")
        ax.set_xlabel("measured F_z = -m a_z [N]")
        ax.set_ylabel("FMU thrust_total_N [N]")
        ax.legend(loc="upper left", fontsize=8)
        parts.append(_png(fig))
    return parts


def _fmt(x: float, spec: str) -> str:
    return "-" if x is None or not np.isfinite(x) else format(x, spec)


def _verdict_cell(verdict: str, gated: bool = True) -> str:
    cls = {"pass": "pass", "FAIL": "fail"}.get(verdict, "")
    return f"<span class='{cls}'>{html.escape(verdict)}{'' if gated or verdict != 'FAIL' else ' (not gated)'}</span>"


def _verdict_table(res: ReplayResult) -> str:
    rows = []
    for m in res.maps:
        s, w = res.scores[m.fmu], res.window_counts(m.fmu)
        band = []
        if res.bands is not None:
            bv, b = res.bands.verdict(m.fmu)[0], res.bands.bounds.get(m.fmu)
            bounds = f" [{100 * b.lower:.0f}, {100 * b.upper:.0f}] %" if b is not None and b.windows else ""
            band = [f"<span class='{'fail' if bv == 'not explained' else ''}'>"
                    f"{_fmt(100 * res.bands.coverage[m.fmu], '.0f')} %{bounds} ({html.escape(bv)})</span>"]
        margin = "" if s.interval is None else f" ({_fmt(s.interval.lo, '+.2f')}..{_fmt(s.interval.hi, '+.2f')})"
        rows.append([m.fmu, _verdict_cell(s.verdict, m.gate), _fmt(s.skill_persistence, "+.2f") + margin,
                     _fmt(s.skill_mean, "+.2f"), *band, f"{w['pass']} / {w['FAIL']} / {w['n/a']}",
                     html.escape(s.reason)])
    return _table(["signal", "verdict", "skill vs persistence (90 % interval)", "skill vs window mean",
                   *(["5-95 % band coverage [95 % bounds from the windows]"] if res.bands is not None else []),
                   "windows pass / FAIL / n/a",
                   "reason"], rows, raw=True) + _band_note(res)


def _band_note(res: ReplayResult) -> str:
    """What the Monte Carlo bands are, and which signals they say the model does not explain."""
    if res.bands is None:
        return ""
    info = res.bands.info
    bad = [f"{m.fmu}: {res.bands.verdict(m.fmu)[1]}" for m in res.maps if res.bands.verdict(m.fmu)[0] ==
           "not explained"]
    learned = (info.get("discrepancy") or {}).get("signals") or []
    parts = (f"convolved with the model discrepancy learned from {len(info['discrepancy']['logs'])} replay(s) on "
             f"{', '.join(learned)} (it carries their sensor noise), sensor noise on the others" if learned else
             "each compared sample with the sensor noise estimated from the log")
    factors = {k: v for k, v in ((info.get("discrepancy") or {}).get("band_factor") or {}).items() if v is not None}
    if factors:
        parts += (", the band stretched about its median by the band factor calibrated on the "
                  "learning replays (" + ", ".join(f"{k} {v:.3g}" for k, v in factors.items()) + ")")
    alone = [k for k, w in ((info.get("discrepancy") or {}).get("parameter_weight") or {}).items() if w == 0.0]
    if alone:
        parts += (f"; on {', '.join(alone)} the discrepancy alone (the parameter draws' spread did not follow the "
                  "error on learning replays left out)")
    offsets = (info.get("discrepancy") or {}).get("offset") or {}
    if offsets:
        parts += ("; centred off the FMU on " + ", ".join(f"{k} ({v})" for k, v in offsets.items())
                  + " (logged - FMU at the restarts of every learning replay: a bias the FMU does not have)")
    text = (f"Bands: {info['draws_run']} of {info['draws']} Monte Carlo replays (seed {info['seed']}) with "
            f"{', '.join(info['parameters'])} drawn from the identified covariance, each window's restart state "
            f"with the sensor noise estimated from the log, {parts}. Nominal level 90 % (the 5-95 % band); "
            "coverage is the share of logged samples inside it, below 80 % or above 98 % a finding when the "
            "replay's windows show it (the coverage's one-sided 95 % bound past the threshold too), else unresolved.")
    out = f"<p>{html.escape(text)}</p>"
    if bad:
        out += "".join(f"<p class='fail'>Not explained by the model and its uncertainty: {html.escape(b)}</p>"
                       for b in bad)
    out += "".join(f"<p>Unresolved: {html.escape(m.fmu)}: {html.escape(res.bands.verdict(m.fmu)[1])}</p>"
                   for m in res.maps if res.bands.verdict(m.fmu)[0] == "unresolved")
    if info["failed"]:
        out += f"<p class='fail'>{len(info['failed'])} draws failed: {html.escape('; '.join(info['failed'][:5]))}</p>"
    return out


def _metrics_table(res: ReplayResult) -> str:
    rows = []
    for m in res.maps:
        s = res.scores[m.fmu]
        r = s.fit
        rule = f"skill > {m.min_skill_persistence:g} and (U < {m.max_theil:g}" + (
            f" or RMSE < {m.max_rmse:g})" if m.max_rmse is not None else ")")
        rows.append([m.fmu, m.log, f"{r.rmse:.4g}", _fmt(s.rmse_persistence, ".4g"), _fmt(s.rmse_mean, ".4g"),
                     _fmt(r.nrmse, ".4f"), f"{r.theil_u:.3f}", _fmt(r.fit_percent, ".1f"), _fmt(r.r2, ".3f"),
                     f"{r.max_error:.4g}", rule])
    return _table(["FMU output", "log signal", "RMSE", "RMSE persistence", "RMSE window mean", "NRMSE", "Theil U",
                   "fit %", "R²", "max error", "pass when"], rows)


def _horizon_section(res: ReplayResult) -> list[str]:
    hs = sorted({row.horizon_s for rows in res.horizons.values() for row in rows})
    if not hs:
        return ["<p>No prediction horizon fits in a replay window.</p>"]
    rows = []
    for name, hrows in res.horizons.items():
        by = {r.horizon_s: r for r in hrows}
        rows.append([name, *(f"{by[h].rmse:.3g} / {by[h].rmse_persistence:.3g} "
                             f"({_fmt(by[h].skill_persistence, '+.2f')})" if h in by else "-" for h in hs)])
    fig, ax = plots.figure(figsize=(6.0, 3.2), layout=None)
    fig.subplots_adjust(left=0.12, right=0.7, top=0.95, bottom=0.16)
    for name, hrows in res.horizons.items():
        ax.plot([r.horizon_s for r in hrows], [r.skill_persistence for r in hrows], "o-", ms=3, lw=1, label=name)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_ylim(-2.0, 1.05)  # below -2 (RMSE three times persistence's) the curves leave the frame
    ax.set_xlabel("prediction horizon [s] (restart from the logged state)")
    ax.set_ylabel("skill vs persistence (clipped at -2)")
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7)
    n = max((r.n for rows_ in res.horizons.values() for r in rows_), default=0)
    return [_table(["signal", *(f"{h:g} s: RMSE FMU / persistence (skill)" for h in hs)], rows),
            f"<p>Each horizon: the error at that lead time after each of {n} restarts from the logged state.</p>",
            _png(fig)]


def _one_step_section(res: ReplayResult) -> str:
    if not res.one_step:
        return "<p>No accelerometer in the log or the FMU: no one-step force check.</p>"
    rows = [[k, f"{s.fit.rmse:.3g}", _fmt(s.rmse_mean, ".3g"), _fmt(s.skill_mean, "+.2f"), f"{s.fit.n}",
             html.escape(s.reason)] for k, s in res.one_step.items()]
    return ("<p>The FMU's specific force (accelerometer output) for the logged state and inputs at each restart, "
            "against the logged accelerometer: a wrong force model shows here, a drifting integration does not.</p>"
            + _table(["output", "RMSE [m/s²]", "RMSE of the log's mean", "skill vs mean", "samples", "note"], rows))


def _log_notes(res: ReplayResult) -> list[str]:
    notes = [f"{sum(res.included)} of {len(res.windows)} replay windows scored, each re-initialised from the logged "
             "state (the first sample of each window is the initial condition and is not scored)."]
    if res.start_std:
        notes.append("Fixed wing: each window's start body velocity v, w is the one whose specific force matches the "
                     "logged one at the restart (--start-velocity logged: the GPS velocity's).")
    if res.excluded or res.ground:
        why = ", ".join(f"{k}: {v}" for k, v in {**res.ground, **res.gaps}.items())
        notes.append(f"{res.excluded} windows excluded ({why}); the vehicle on the ground is left out by default "
                     "(--include-ground scores it), windows without data for an input or compared signal always.")
    notes += [f"log warning: {w}" for w in res.log["warnings"]]
    notes += [f"data quality: {w}" for w in res.log.get("quality_lines", [])]
    return [f"<p>{html.escape(n)}</p>" for n in notes]


def validation_page(res: ReplayResult) -> str:
    """One FMU against one log: the verdict table first, then metrics beside the baselines, horizons, the
    one-step force check, identities, overlays with the persistence baseline, residuals."""
    fmu, log = res.fmu, res.log
    params = _table(["parameter", "value"], [[k, f"{v:.6g}"] for k, v in fmu["parameters"].items()])
    verdict = {"pass": "all gated signals pass", "fail": f"FAILED: {', '.join(res.failed)}",
               "tie": f"TIE: {', '.join(res.ties)} not better than persistence with confidence",
               "unscored": "NOT SCORED: no gated signal has a verdict",
               "band": f"BANDS MISCALIBRATED: {', '.join(res.band_misses)} (prediction band coverage far from its "
                       "nominal level)"}[res.status]
    parts = [
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>uavfmu validation</title><style>{STYLE}</style>"
        "</head><body>",
        f"<h1>{html.escape(fmu['model_name'])} against {html.escape(log['path'])}</h1>",
        _verdict_table(res),
        f"<p class='{'pass' if res.status == 'pass' else 'fail'}'>{html.escape(verdict)}. A signal passes only "
        "when it beats persistence (the logged value at the window start, held) over the whole 90 % block-bootstrap "
        "interval of its skill and meets its accuracy threshold; a skill whose interval reaches zero is a tie.</p>",
        *_input_checks(res),
        *_log_notes(res),
        "<h2>Metrics beside the baselines</h2>", _metrics_table(res),
        "<h2>Error against prediction horizon</h2>", *_horizon_section(res),
        "<h2>One-step force check</h2>", _one_step_section(res),
        "<h2>FMU</h2>",
        _table(["field", "value"], [[k, fmu[k]] for k in ("path", "model_name", "guid", "generation_tool",
                                                           "generated")] + [["overrides", fmu["overrides"]]]),
        f"<details><summary>parameters used ({len(fmu['parameters'])})</summary>{params}</details>",
        "<h2>Log</h2>",
        _table(["field", "value"], [[k, log[k]] for k in ("path", "format", "vehicle", "duration_s", "sha256")]),
        "<h2>Signals</h2>", *_signal_figures(res), "</body></html>",
    ]
    return "\n".join(parts)


def _input_checks(res: ReplayResult) -> list[str]:
    """The logged inputs outside what the FMU was built for (``identification.validation.input_check``)."""
    if not res.input_checks:
        return []
    rows = [[f.input, f.check, f.logged, f.expected, f.fed] for f in res.input_checks]
    return ["<h2 class='fail'>Inputs outside what the FMU was built for</h2>",
            _table(["input", "check", "logged", "the FMU expects", "fed"], rows)]


def index_page(results: Sequence[dict[str, Any]]) -> str:
    """Batch summary: one row per FMU x log, failures with their messages, links to the job reports."""
    rows = []
    for r in results:
        link = f"<a href='{html.escape(r['report'])}'>report</a>" if r.get("report") else ""
        cls = {"pass": "pass"}.get(r["status"], "fail")
        sig = r.get("signals") or {}
        why = "; ".join(f"{s}: {sig[s]['reason']}" for s in r.get("failed", []) if s in sig)
        rows.append([html.escape(r["fmu"]), html.escape(r["log"]), f"<span class='{cls}'>{r['status']}</span>",
                     html.escape(why), html.escape(r.get("error", "")), link])
    n_bad = sum(r["status"] != "pass" for r in results)
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>uavfmu batch validation</title>"
            f"<style>{STYLE}</style></head><body><h1>Batch validation: {len(results)} runs, {n_bad} not passing"
            "</h1>" + _table(["FMU", "log", "status", "failed signals and why", "error", ""], rows, raw=True)
            + "</body></html>")
