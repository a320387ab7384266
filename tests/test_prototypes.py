"""harness/cosim/prototypes.py: FMPy's FMU classes with the prototypes of the FMI functions
worked out once per class. The oracle is FMPy itself: an object of FMPy's own class, made
beside ours, loads the same functions with the same prototypes, and both run the FMU to the
same numbers."""

from __future__ import annotations

from pathlib import Path

import fmpy
import pytest
from fmpy import fmi2, fmi3

from dronefly.harness.cosim import prototypes
from shared_files import need_shared

SHARED = Path(__file__).resolve().parents[2] / "shared" / "reference-fmus"

#: (FMI version folder, interface, our class, FMPy's class)
CLASSES = [("fmi2", "coSimulation", prototypes.FMU2Slave, fmi2.FMU2Slave),
           ("fmi2", "modelExchange", prototypes.FMU2Model, fmi2.FMU2Model),
           ("fmi3", "coSimulation", prototypes.FMU3Slave, fmi3.FMU3Slave),
           ("fmi3", "modelExchange", prototypes.FMU3Model, fmi3.FMU3Model)]


def _make(cls, md, folder, interface):
    token = md.guid if md.fmiVersion == "2.0" else md.instantiationToken
    return cls(guid=token, unzipDirectory=folder,
               modelIdentifier=getattr(md, interface).modelIdentifier, instanceName="x")


@pytest.mark.parametrize("version, interface, ours, theirs", CLASSES,
                         ids=[f"{v}-{i}" for v, i, _, _ in CLASSES])
def test_the_recorded_prototypes_are_fmpys(version, interface, ours, theirs, tmp_path):
    """VanDerPol (both interfaces): the third object of our class, made from the recorded
    prototypes, has FMPy's functions with FMPy's argument names, argument and result types,
    and gives FMPy's numbers."""
    fmu = SHARED / version / "VanDerPol.fmu"
    need_shared(fmu, "the Reference-FMUs")
    md = fmpy.read_model_description(str(fmu))
    folder = fmpy.extract(str(fmu), str(tmp_path / "x"))
    first = _make(ours, md, folder, interface)
    assert type(first) in prototypes._PROTOTYPES
    plain, cached = _make(theirs, md, folder, interface), _make(ours, md, folder, interface)
    want = {n: (f.argnames, f.argtypes, f.restype) for n, f in plain._functions.items()}
    got = {n: (f.argnames, f.argtypes, f.restype) for n, f in cached._functions.items()}
    assert len(want) > 30 and got == want
    assert all(cached._functions[n] is not plain._functions[n] for n in want)  # its own library
    if interface == "coSimulation":
        results = []
        for slave in (plain, cached):
            slave.instantiate()
            if version == "fmi2":
                slave.setupExperiment(startTime=0.0)
            slave.enterInitializationMode()
            slave.exitInitializationMode()
            for k in range(10):
                slave.doStep(0.01 * k, 0.01)
            vrs = [v.valueReference for v in md.modelVariables if v.name in ("x0", "x1")]
            results.append(list(slave.getReal(vrs) if version == "fmi2"
                                else slave.getFloat64(vrs)))
            slave.terminate()
            slave.freeInstance()
        assert results[0] == results[1] and len(results[0]) == 2
