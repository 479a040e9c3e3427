"""FMU life-cycle stress: hundreds of instantiate/step/free cycles, a batch of
many FMU x log pairs, wrong calls mixed in, and the process exit, for both backends, each in a subprocess so a
heap corruption (glibc's ``corrupted double-linked list`` abort, exit 134) or a segfault fails the test.

Root cause of the batch abort, for the record (fmu_models/fmi/shim.py and fmu_models/fmi/build.py hold the
details): pythonfmu 0.7's export library releases its interpreter guard twice at ``exit()`` (static
``shared_ptr`` destructor, then a library destructor on the destroyed pointer: a write into freed heap), releases
a slave's Python objects twice after any Python exception (fatal status, then free), and drops one reference
too many of the slave module's globals at every instantiation. The shim and the generated slave module
neutralise all three; these tests drive exactly those paths.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from identification.flights import synthetic

REPO = Path(__file__).resolve().parents[3]
CYCLES = REPO / "tests" / "fmu_models" / "fmi" / "fmi_cycles.py"
ABORT_SIGNS = ("corrupted", "double free", "free():", "malloc():", "Segmentation", "Traceback")
TIMEOUT_S = 240


def run_python(code: str, *args: str, timeout: float = TIMEOUT_S) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=timeout,
                          cwd=REPO, env=env, check=False)


def assert_clean(proc: subprocess.CompletedProcess[str], ok_codes: tuple[int, ...] = (0,)) -> None:
    bad = [s for s in ABORT_SIGNS if s in proc.stderr]
    assert proc.returncode in ok_codes and not bad, (
        f"exit {proc.returncode} (134 = abort, 139 = segfault), {bad}:\n{proc.stdout[-1500:]}\n{proc.stderr[-3000:]}")


@pytest.fixture(scope="module", params=["python", "native"])
def backend_fmus(request: pytest.FixtureRequest, built_fmus: dict[str, Path],
                 python_fmus: dict[str, Path]) -> tuple[str, dict[str, Path]]:
    return request.param, (python_fmus if request.param == "python" else built_fmus)


def test_instantiate_free_cycles_do_not_leak(backend_fmus: tuple[str, dict[str, Path]], capsys) -> None:
    """1000 instantiate/initialise/step/free cycles after a warm-up grow the process by < 1 MB."""
    backend, fmus = backend_fmus
    for name, fmu in fmus.items():
        proc = subprocess.run([sys.executable, str(CYCLES), str(fmu), "1000", "5"], capture_output=True, text=True,
                              timeout=TIMEOUT_S, cwd=REPO, check=False)
        assert_clean(proc)
        res = json.loads(proc.stdout.strip().splitlines()[-1])
        with capsys.disabled():
            print(f"\n[leak] {backend} {name}: {res['cycles']} cycles after {res['warmup']} warm-up: "
                  f"+{res['growth_kib']} KiB ({res['per_cycle_kib']:.3f} KiB/cycle; with warm-up "
                  f"+{res['growth_with_warmup_kib']} KiB) in {res['seconds']:.1f} s")
        assert res["growth_kib"] < 1024, res


HOST_CYCLES = textwrap.dedent("""
    import sys
    import numpy as np
    from fmu_models.fmi.host import FmuHost, FmuRunError

    t = np.arange(0.0, 0.5, 0.02)
    wrong = 0
    for k in range(int(sys.argv[1])):
        fmu = sys.argv[2 + k % (len(sys.argv) - 2)]
        with FmuHost(fmu, instance_name=f"stress{k}") as host:
            if host.vehicle == "quadrotor":
                u = {f"pwm_{i}_us": np.full(len(t), 1400.0) for i in range(1, 5)}
            else:
                u = {"aileron_rad": np.zeros(len(t)), "elevator_rad": np.zeros(len(t)), "rudder_rad": np.zeros(len(t)),
                     "throttle": np.full(len(t), 0.5)}
            for _ in range(2):  # two windows: the second resets the instance
                res = host.simulate(t, u, ["altitude_m"])
                assert np.all(np.isfinite(res["altitude_m"]))
            host.start()
            for call in (lambda: host.step(0.5, 0.01), lambda: host.step(0.0, -1.0), lambda: host.get(["nope"])):
                try:  # refused before the binary sees them: an error, never a crash
                    call()
                except FmuRunError:
                    wrong += 1
            host.step(0.0, 0.01)
            host.terminate()
            try:
                host.step(0.01, 0.01)  # doStep after terminate
            except FmuRunError:
                wrong += 1
            if k % 25 == 0:
                host.reinstantiate()  # the path after a fatal status: free and instantiate afresh
                host.start()
                host.step(0.0, 0.01)
    print("cycles", sys.argv[1], "refused", wrong)
""")


def test_hundreds_of_host_cycles_then_clean_exit(backend_fmus: tuple[str, dict[str, Path]]) -> None:
    """300 FmuHost lives (simulate, reset, wrong calls, terminate, reinstantiate), both vehicles, then exit()."""
    _, fmus = backend_fmus
    proc = run_python(HOST_CYCLES, "300", *(str(p) for p in fmus.values()))
    assert_clean(proc)
    assert "cycles 300 refused 1200" in proc.stdout, proc.stdout


BATCH = textwrap.dedent("""
    import sys
    from fmu_models.fmi.host import FmuHost
    from uavfmu.cli import main

    with FmuHost(sys.argv[2]) as host:  # an FMU used in the parent before the pool forks (the demo's pattern)
        host.start()
        host.step(0.0, 0.01)
    sys.exit(main(["validate", "--batch", sys.argv[1], "--jobs", "2", "--quiet", "--report", sys.argv[3]]))
""")


def test_batch_of_many_fmu_log_pairs(built_fmus: dict[str, Path], python_fmus: dict[str, Path],
                                     tmp_path: Path) -> None:
    """4 FMUs (both vehicles, both backends) x 3 logs in one batch on two pool workers: every pair gets a verdict, no
    abort. One batch of 12 pairs (it was three batches of 24 while the abort's cause was being found): the exit-time
    paths that aborted are now driven deterministically by the hundreds of host cycles above and under valgrind
    below; here what is left is the pool, FMUs opened in the parent before it forks, and both backends in one run."""
    logs = []
    for k in range(3):
        t, sig = synthetic.fixed_wing_flight(seconds=6.0 + k, rate_hz=50.0)
        logs.append(synthetic.write_csv_log(tmp_path / f"wing{k}.csv", t, sig).name)
    synthetic.write_mapping_toml(tmp_path / "mapping.toml")
    fmus = [str(p) for p in (*python_fmus.values(), *built_fmus.values())]
    (tmp_path / "batch.toml").write_text(
        "[defaults]\nwindow_s = 2.0\nmapping = 'mapping.toml'\n"
        f"[[job]]\nfmu = {json.dumps(fmus)}\nlog = {json.dumps(logs)}\n")
    report = tmp_path / "report"
    proc = run_python(BATCH, str(tmp_path / "batch.toml"), str(python_fmus["quadrotor"]), str(report))
    assert_clean(proc, ok_codes=(0, 1))
    results = json.loads((report / "results.json").read_text())
    assert len(results) == len(fmus) * len(logs)
    assert not [r for r in results if "worker process failed" in r.get("error", "")], results
    assert sum(r["status"] != "error" for r in results) == 2 * len(logs)  # fixed-wing FMUs score every log


EXIT_ONLY = textwrap.dedent("""
    import sys
    from fmu_models.fmi.host import FmuHost
    host = FmuHost(sys.argv[1])
    host.start()
    host.step(0.0, 0.01)
    # left open on purpose: the process exits with the instance and pythonfmu's library still loaded
""")


#: libraries of our FMUs: the guarding shim, pythonfmu's export library and the generated model code
OUR_LIBRARIES = ("quadrotor.so", "quadrotor_pythonfmu.so", "quadrotor_model.so")


def errors_in_our_code(xml_file: Path) -> list[str]:
    """Valgrind memory errors (``--xml=yes``: invalid reads/writes/frees, uninitialised values, overlaps...) with
    any stack frame, of the error or of its freed/allocated block, in one of ``OUR_LIBRARIES``; CPython's own
    reports are not ours to fix, and leak records are not errors here (the process exits with an instance
    deliberately left alive, so everything it holds is still allocated)."""
    from xml.etree import ElementTree as ET

    found = []
    for err in ET.parse(xml_file).getroot().iter("error"):
        if (err.findtext("kind") or "").startswith("Leak_"):
            continue
        objs = [Path(o.text or "").name for o in err.iter("obj")]
        if any(o in OUR_LIBRARIES for o in objs):
            fns = [f.text or "?" for f in err.iter("fn")]
            found.append(f"{err.findtext('kind')}: {err.findtext('what') or err.findtext('xwhat/text')} "
                         f"in {' <- '.join(fns[:6])}")
    return found


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind not installed (apt-get install valgrind)")
def test_exit_with_a_live_pythonfmu_instance_has_no_memory_error_in_our_code(python_fmus: dict[str, Path],
                                                                            tmp_path: Path) -> None:
    """The exit-time use-after-free in pythonfmu's library (the batch abort's root cause) stays neutralised, and
    no other memory error of any kind comes from the shim, pythonfmu's library or the model code."""
    env = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONMALLOC": "malloc"}
    xml = tmp_path / "valgrind.xml"
    proc = subprocess.run(["valgrind", "--xml=yes", f"--xml-file={xml}", sys.executable, "-c", EXIT_ONLY,
                           str(python_fmus["quadrotor"])], capture_output=True, text=True, timeout=TIMEOUT_S,
                          cwd=REPO, env=env, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "<valgrindoutput>" in xml.read_text()  # valgrind did run and report
    found = errors_in_our_code(xml)
    assert not found, "\n".join(found)[:3000]
