"""Fuzz groups of random call sequences: ``random`` (N random calls with random arguments on
one instance) and ``churn`` (interleaved instances of one FMU, two loads of its library).

Part of the child side of :mod:`.fuzz` (see :mod:`.fuzzcases`, which runs the groups).
"""

from __future__ import annotations

import math
import random
from typing import Any, Callable

from .fuzzkit import OK, Case, experiment, instantiate, reals, to_state
from ..cosim.fmu import FMU, Instance

__all__ = ["group_churn", "group_random"]

Cases = list[tuple[str, Callable[[], dict[str, Any]]]]


def group_random(fmu: FMU, ours: bool, seed: int, n: int) -> Cases:
    return [(f"{n} random calls (seed {seed})", lambda: _random_calls(fmu, ours, seed, n))]


def _random_calls(fmu: FMU, ours: bool, seed: int, n: int) -> dict[str, Any]:
    """``n`` random calls with random arguments on one instance (reset when stuck)."""
    rng = random.Random(seed)
    _, step = experiment(fmu)
    reals = [v.valueReference for v in fmu.model_description.modelVariables if v.type == "Real"]
    bools = [v.valueReference for v in fmu.model_description.modelVariables
             if v.type == "Boolean"]
    values = [0.0, 1.0, -1.0, math.nan, math.inf, 1e300, 0.1, -0.4]
    with instantiate(fmu, "fuzz") as inst:
        c = Case(f"{n} random calls (seed {seed})", inst, ours)
        t = 0.0
        states: list[Any] = []
        for _ in range(n):
            k = rng.randrange(14)
            if k == 0:
                c.call("setupExperiment", None, rng.choice([0.0, t, -1.0]))
            elif k == 1:
                c.call("enterInitializationMode")
            elif k == 2:
                c.call("exitInitializationMode")
            elif k in (3, 4, 5):
                h = rng.choice([step, step, 0.5 * step, 0.0, -step, math.inf, 1e300])
                c.call("doStep", rng.choice([t, t, t + step, math.inf]), h)
                if c.statuses[-1] == OK:  # FMPy's FMI 2.0 doStep returns nothing
                    t += h
            elif k == 6:
                c.call("terminate")
            elif k == 7:
                c.call("reset")
                t = 0.0
            elif k == 8:
                c.call("getReal", rng.sample(reals, min(3, len(reals))) + [rng.choice([0, 2**31 - 1])])
            elif k == 9:
                vr = rng.sample(reals, min(2, len(reals)))
                c.call("setReal", vr, [rng.choice(values) for _ in vr])
            elif k == 10 and bools:
                c.call("getBoolean", bools)
                c.call("setBoolean", bools, [rng.random() < 0.5 for _ in bools])
            elif k == 11:
                st = c.call("getFMUstate")
                if st is not None:
                    states.append(st)
            elif k == 12 and states:
                c.call("setFMUstate", rng.choice(states))
            elif k == 13 and states:
                st = states[-1]
                blob = c.call("serializeFMUstate", st)
                if blob is not None:
                    st2 = c.call("deSerializeFMUstate", bytes(blob))
                    if st2 is not None:
                        c.call("setFMUstate", st2)
                        c.call("freeFMUstate", st2)
        for st in states:
            c.call("freeFMUstate", st)
        return c.result()


def group_churn(fmu: FMU, ours: bool, seed: int, n: int) -> Cases:
    return [(f"{n} interleaved instances", lambda: _churn(fmu, ours, seed, n))]


def _churn(fmu: FMU, ours: bool, seed: int, n: int) -> dict[str, Any]:
    """``n`` instances created, stepped and freed in random order give the single run."""
    rng = random.Random(seed)
    _, step = experiment(fmu)
    vr_out = [v.valueReference for v in reals(fmu, "output")]

    def run(inst: Instance, steps: int) -> Any:
        c = Case("run", inst, ours)
        to_state(c, "stepping")
        for k in range(steps):
            c.call("doStep", k * step, step)
        return c.call("getReal", vr_out)

    with instantiate(fmu, "ref") as ref:
        expected = list(run(ref, 3) or [])
    c = Case(f"{n} interleaved instances", ref, ours)
    live = [instantiate(fmu, f"i{k}") for k in range(n)]
    rng.shuffle(live)
    for inst in live:
        got = run(inst, 3)
        if got is None or list(got) != expected:
            c.problems.append(f"instance {inst.name} gave {got}, the single run {expected}")
    rng.shuffle(live)
    for inst in live:
        inst.free()
    with FMU(fmu.path) as again, instantiate(again, "second load") as inst:
        got = run(inst, 3)  # a second extraction: another load of the same library
        if got is None or list(got) != expected:
            c.problems.append(f"a second load of the library gave {got}")
    return c.result()
