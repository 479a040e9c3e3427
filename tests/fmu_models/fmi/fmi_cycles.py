"""Instantiate/free cycles of one FMU in this process; prints the resident-set growth as JSON.

``python tests/fmu_models/fmi/fmi_cycles.py FMU CYCLES [STEPS]``: each cycle instantiates through FMPy's FMU2Slave,
initialises, makes ``STEPS`` steps of 10 ms, reads the outputs and frees the instance (the library stays
loaded, as in an importer that runs many instances). Prints the growth over all cycles and over the
cycles after a warm-up of 200: the first ones carry one-off costs (pythonfmu's first instantiation imports
the slave and loads its libraries, ~4 MB; the allocator settles within ~200 cycles), a leak keeps growing
after them. Run in a subprocess by tests/fmu_models/fmi/test_fmu_stress.py.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

WARMUP = 200


def rss_kib() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def main(fmu: str, cycles: int, steps: int) -> dict[str, float]:
    md = read_model_description(fmu)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="cycles")
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    t0 = time.perf_counter()
    start, base = rss_kib(), 0
    for k in range(WARMUP + cycles):
        if k == WARMUP:
            base, t0 = rss_kib(), time.perf_counter()
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        for i in range(steps):
            slave.doStep(currentCommunicationPoint=0.01 * i, communicationStepSize=0.01)
        slave.getReal(outputs)
        slave.fmi2FreeInstance(slave.component)
    growth = rss_kib() - base
    slave.freeLibrary()
    return {"cycles": cycles, "warmup": WARMUP, "growth_kib": growth, "per_cycle_kib": growth / cycles,
            "growth_with_warmup_kib": rss_kib() - start, "seconds": time.perf_counter() - t0}


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 5)))
