"""A system of FMI 2.0 co-simulation FMUs: named instances, connections, parameter values.

Built in Python, read from an SSP file (SSD connections and parameter bindings, SSV values),
or connected by name. Checked when opened (:mod:`.graph`): every connection joins an output
to an input of the same type and unit, every input has at most one source.
"""

from __future__ import annotations

import math
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from fmpy import read_model_description
from fmpy.ssp.ssd import read_ssd

from ...core.errors import DroneflyError

__all__ = ["Connection", "System", "SystemSpecError"]


class SystemSpecError(DroneflyError):
    """A system description that cannot be co-simulated (names the offending item)."""


@dataclass(frozen=True)
class Connection:
    """``source.output`` drives ``target.input``."""

    source: str
    output: str
    target: str
    input: str

    def __str__(self) -> str:
        return f"{self.source}.{self.output} -> {self.target}.{self.input}"


@dataclass
class System:
    """FMUs by instance name, connections, and start/parameter values by instance.

    ``parameters[instance][name]`` is set in initialization mode, in the FMU's unit. Inputs
    that no connection drives keep their start value (or a value given here).
    """

    fmus: dict[str, Path]
    connections: list[Connection] = field(default_factory=list)
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    name: str = "system"
    step_s: float | None = None  # from the SSP's annotations or the caller
    stop_s: float | None = None
    _tmp: Any = field(default=None, repr=False, compare=False)
    start_s: float = 0.0  # the SSP's DefaultExperiment startTime, s

    def __post_init__(self) -> None:
        self.fmus = {k: Path(v) for k, v in self.fmus.items()}
        for inst in self.parameters:
            if inst not in self.fmus:
                raise SystemSpecError(f"parameter values for instance {inst!r}, which the system "
                                   f"does not have (instances: {', '.join(self.fmus)})")
        seen: dict[tuple[str, str], Connection] = {}
        for c in self.connections:
            for inst in (c.source, c.target):
                if inst not in self.fmus:
                    raise SystemSpecError(f"connection {c} names instance {inst!r}, which the "
                                       f"system does not have (instances: {', '.join(self.fmus)})")
            key = (c.target, c.input)
            if key in seen:
                raise SystemSpecError(f"input {c.target}.{c.input} has two sources: "
                                   f"{seen[key].source}.{seen[key].output} and {c.source}.{c.output}")
            seen[key] = c

    def with_values(self, values: Mapping[str, Any]) -> "System":
        """A copy with ``{"instance.NAME": value}`` added to the parameter values."""
        params = {k: dict(v) for k, v in self.parameters.items()}
        for key, value in values.items():
            inst, _, name = key.partition(".")
            if not name or inst not in self.fmus:
                raise SystemSpecError(f"{key!r}: expected instance.NAME with an instance of "
                                   f"{', '.join(self.fmus)}")
            params.setdefault(inst, {})[name] = value
        return self.with_parameters(params)

    def with_parameters(self, parameters: Mapping[str, Mapping[str, Any]]) -> "System":
        """A copy with ``parameters`` (``{instance: {name: value}}``) in place of its own
        (the same FMU files, extracted ones included)."""
        return System(self.fmus, list(self.connections),
                      {i: dict(v) for i, v in parameters.items()}, self.name, self.step_s,
                      self.stop_s, self._tmp, self.start_s)

    @classmethod
    def by_name(cls, fmus: Mapping[str, Any], **kw: Any) -> "System":
        """Every input driven by the output of the same name of another instance.

        ``fmus`` maps instances to FMU files or to opened
        :class:`~dronefly.harness.cosim.fmu.FMU` objects (their model descriptions are
        used; the system holds their paths). An input that no other instance provides stays
        unconnected; one that two instances provide is refused.
        """

        outputs: dict[str, list[str]] = {}
        inputs: dict[str, list[str]] = {}
        for inst, f in fmus.items():
            md = getattr(f, "model_description", None) or read_model_description(str(f))
            for v in md.modelVariables:
                if v.causality == "output":
                    outputs.setdefault(v.name, []).append(inst)
                elif v.causality == "input":
                    inputs.setdefault(inst, []).append(v.name)
        cons = []
        for inst, names in inputs.items():
            for name in names:
                sources = [s for s in outputs.get(name, []) if s != inst]
                if len(sources) > 1:
                    raise SystemSpecError(f"input {inst}.{name} could be driven by "
                                       f"{' or '.join(f'{s}.{name}' for s in sources)}: "
                                       "connect it explicitly")
                if sources:
                    cons.append(Connection(sources[0], name, inst, name))
        return cls({i: getattr(f, "path", f) for i, f in fmus.items()}, cons, **kw)

    @classmethod
    def from_ssp(cls, path: str | Path) -> "System":
        """Read an SSP: its components (FMUs inside the archive), connections and the
        parameter values bound to each component (SSV files or inline)."""

        path = Path(path)
        if not path.is_file():
            raise SystemSpecError(f"SSP file {str(path)!r} does not exist")
        try:
            ssd = read_ssd(str(path))
        except Exception as e:  # fmpy's schema errors: the first line says it
            text = str(e).strip().splitlines()[0] if str(e).strip() else repr(e)
            raise SystemSpecError(f"{str(path)!r} is not a readable SSP: {text}") from e
        tmp = tempfile.TemporaryDirectory(prefix="dronefly_ssp_")
        with zipfile.ZipFile(path) as z:
            z.extractall(tmp.name)
        system = ssd.system
        fmus, params = {}, {}
        for e in system.elements:
            if getattr(e, "source", None) is None or not str(e.source).endswith(".fmu"):
                raise SystemSpecError(f"SSP element {e.name!r} is not an FMU component "
                                   "(nested systems are not supported)")
            fmus[e.name] = Path(tmp.name, e.source)
            if not fmus[e.name].is_file():  # named by the SSP and the component, not tmp
                tmp.cleanup()
                raise SystemSpecError(f"SSP file {str(path)!r}: component {e.name!r} names "
                                      f"{str(e.source)!r}, which the SSP does not contain")
            values = {}
            for binding in e.parameterBindings or []:
                prefix = binding.prefix or ""  # SSP 1.0: removed from the names it binds
                for pset in binding.parameterValues or []:
                    for p in pset.parameters:
                        name = p.name[len(prefix):] if p.name.startswith(prefix) else p.name
                        values[name] = _ssv_value(p)
            if values:
                params[e.name] = values
        cons = [Connection(c.startElement, c.startConnector, c.endElement, c.endConnector)
                for c in system.connections]
        sys_ = cls(fmus, cons, params, name=system.name or path.stem)
        sys_._tmp = tmp  # the extracted FMUs live as long as the system
        ssd_file = Path(tmp.name, "SystemStructure.ssd")
        sys_.stop_s = _experiment_time(ssd_file, "stopTime")
        sys_.start_s = _experiment_time(ssd_file, "startTime") or 0.0
        return sys_


def _experiment_time(ssd: Path, attribute: str) -> float | None:
    """The DefaultExperiment's ``attribute`` (``startTime``, ``stopTime``) of an SSD, s, or None
    where it gives none (fmpy 0.3 reads neither). A stop time must be > 0."""

    for el in ET.parse(ssd).getroot():
        text = el.get(attribute)
        if el.tag.rsplit("}", 1)[-1] != "DefaultExperiment" or text is None:
            continue
        try:
            value = float(text)
        except ValueError as e:
            raise SystemSpecError(f"DefaultExperiment {attribute} = {text!r} is not a number") from e
        if not math.isfinite(value) or (attribute == "stopTime" and value <= 0):
            raise SystemSpecError(f"DefaultExperiment {attribute} = {value!r} s must be finite"
                                  + (" and > 0" if attribute == "stopTime" else ""))
        return value
    return None


def _ssv_value(p: Any) -> Any:
    """An SSV parameter's value as its SSV type says (converted to the FMU variable's type
    when the system is opened, :mod:`.typed_values`; an Enumeration given by an item name stays
    that name, resolved there against the variable's type definition)."""
    kind = (p.type or "Real").lower()
    if kind == "string":
        return str(p.value)
    if kind == "boolean":
        return str(p.value).strip().lower() in ("true", "1")
    if kind == "enumeration":  # a number, or an item name resolved against the FMU's type
        text = str(p.value).strip()
        return int(text) if text.lstrip("+-").isdigit() else text
    try:
        return int(p.value) if kind in ("integer", "enumeration") else float(p.value)
    except (TypeError, ValueError) as e:
        raise SystemSpecError(f"SSV parameter {p.name} = {p.value!r} is not a valid "
                              f"{p.type or 'Real'}") from e
