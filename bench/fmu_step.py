"""Cost of one 1 ms co-simulation step (set inputs + doStep + get outputs) through FMPy's FMU2Slave.

For each of our FMUs, next to two references measured in the same run:
(a) pythonfmu's floor: a trivial pythonfmu FMU with the same numbers of inputs and outputs, whose
    ``do_step`` only copies one input to the outputs;
(b) JSBSim's F450 quadrotor (``jsbsim`` from PyPI, a bench extra) stepped at 1 ms through its Python API,
    setting 4 throttle commands and reading as many outputs as our FMU exposes.
Targets (issue 2): each FMU <= 2.0x JSBSim's F450 step and <= 1.5x the pythonfmu floor.

Run: ``.venv/bin/python bench/fmu_step.py [--steps N]``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import textwrap
import time
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

TRIVIAL = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class Floor(Fmi2Slave):
    """{n_in} inputs, {n_out} outputs, do_step copies."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = [1000.0] * {n_in}
        self.y = [0.0] * {n_out}
        for i in range({n_in}):
            self.register_variable(Real(f"u{{i}}", causality=Fmi2Causality.input, start=1000.0,
                                        getter=lambda i=i: self.u[i], setter=lambda v, i=i: self.u.__setitem__(i, v)))
        for i in range({n_out}):
            self.register_variable(Real(f"y{{i}}", causality=Fmi2Causality.output, getter=lambda i=i: self.y[i]))

    def do_step(self, current_time, step_size):
        self.y[0] = self.u[0]
        return True
'''


def build_floor(n_in: int, n_out: int, out_dir: Path) -> Path:
    from pythonfmu import FmuBuilder

    out_dir.mkdir(parents=True, exist_ok=True)
    script = out_dir / "floor.py"
    script.write_text(textwrap.dedent(TRIVIAL.format(n_in=n_in, n_out=n_out)))
    return Path(FmuBuilder.build_FMU(script, dest=out_dir))


def time_fmu(fmu: Path, inputs: dict[str, float], outputs: list[str], steps: int, repeats: int = 5) -> float:
    """Median seconds per step over ``repeats`` runs of ``steps`` steps."""
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    in_vr = [vr[n] for n in inputs]
    in_val = list(inputs.values())
    out_vr = [vr[n] for n in outputs]
    t = 0.0
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(steps):
            s.setReal(in_vr, in_val)
            s.doStep(t, 0.001)
            s.getReal(out_vr)
            t += 0.001
        runs.append((time.perf_counter() - t0) / steps)
    s.terminate()
    s.freeInstance()
    return statistics.median(runs)


def time_jsbsim(n_out: int, steps: int, repeats: int = 5) -> float:
    import jsbsim

    fdm = jsbsim.FGFDMExec(None)
    fdm.set_debug_level(0)
    fdm.load_model("F450")
    fdm.set_dt(0.001)
    fdm["ic/h-sl-ft"] = 100.0
    fdm.run_ic()
    props = ["position/h-sl-ft", "position/lat-gc-deg", "position/long-gc-deg", "attitude/phi-rad",
             "attitude/theta-rad", "attitude/psi-rad", "velocities/p-rad_sec", "velocities/q-rad_sec",
             "velocities/r-rad_sec", "velocities/v-north-fps", "velocities/v-east-fps", "velocities/v-down-fps",
             "accelerations/a-pilot-x-ft_sec2", "accelerations/a-pilot-y-ft_sec2",
             "accelerations/a-pilot-z-ft_sec2", "velocities/u-fps", "velocities/v-fps", "velocities/w-fps"]
    props = (props * (n_out // len(props) + 1))[:n_out]
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(steps):
            for i in range(4):
                fdm[f"fcs/throttle-cmd-norm[{i}]"] = 0.5
            fdm.run()
            [fdm[p] for p in props]
        runs.append((time.perf_counter() - t0) / steps)
    return statistics.median(runs)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4000)
    args = parser.parse_args()
    from build_fmus import build

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        fmus = {p.stem: p for p in build(None, out)}
        cases = {
            "quadrotor": {f"pwm_{i}_us": 1530.0 for i in range(1, 5)},
            "fixed_wing": {"aileron_rad": 0.0, "elevator_rad": -0.1, "rudder_rad": 0.0, "throttle": 0.6},
        }
        print(f"{'FMU':<11} {'outputs':>7} {'ours us':>8} {'floor us':>9} {'JSBSim us':>10} "
              f"{'/floor':>7} {'/JSBSim':>8}")
        for name, inputs in cases.items():
            if name not in fmus:
                continue
            md = read_model_description(str(fmus[name]))
            outputs = [v.name for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
            floor = build_floor(len(inputs), len(outputs), out / f"floor_{name}")
            floor_inputs = {f"u{i}": v for i, v in enumerate(inputs.values())}
            t_ours = time_fmu(fmus[name], inputs, outputs, args.steps)
            t_floor = time_fmu(floor, floor_inputs, [f"y{i}" for i in range(len(outputs))], args.steps)
            try:
                t_jsb = time_jsbsim(len(outputs), args.steps)
            except ImportError:
                t_jsb = float("nan")
            print(f"{name:<11} {len(outputs):>7} {t_ours * 1e6:>8.1f} {t_floor * 1e6:>9.1f} {t_jsb * 1e6:>10.1f} "
                  f"{t_ours / t_floor:>7.2f} {t_ours / t_jsb:>8.2f}")
        print("targets: /floor <= 1.5, /JSBSim <= 2.0")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
