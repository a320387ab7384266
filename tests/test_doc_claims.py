"""What the docs and the help texts state is what the code does: the
options a command lists, the FMI versions it accepts, the number of FMUs, what a documented
command prints, and which statements are measurements and which conjecture."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest
from docnumbers import doc_block

from dronefly.harness.builder.build import FMUS
from dronefly.cli.app import _parser, main
from dronefly.models.lateral_interface import FLIGHT_DATA

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
_WORDS = {"two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8,
          "nine": 9, "ten": 10, "eleven": 11, "twelve": 12}


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    p = _parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


@pytest.mark.parametrize("name", list(_subparsers()))
def test_help_names_only_options_the_command_has(name):
    """Every --option a command's help mentions (its options, descriptions and examples) is
    one of its own: `sweep --help` listed --x0 and --step, which only cosim has."""
    sp = _subparsers()[name]
    have = {o for a in sp._actions for o in a.option_strings}
    used = set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", sp.format_help()))
    assert used - have == set(), f"dronefly {name} --help names options it does not have"


def test_fmi_versions_the_help_states_are_those_the_commands_accept(built_fmus3, tmp_path):
    """cosim --system and floquet --plant run FMI 3.0 FMUs; their help and the README say so
    (an "FMI 2.0" of a help text or of the README's command table is "FMI 2.0 or 3.0")."""
    subs = _subparsers()
    cosim = " ".join(subs["cosim"].format_help().split())
    floquet = " ".join(subs["floquet"].format_help().split())
    assert "any number of FMI 2.0 or 3.0 CS FMUs" in cosim
    assert "any FMI 2.0 or 3.0 CS FMU that can get and set its state" in floquet
    table = [line for line in (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
             if line.startswith("| `dronefly ")]
    for text in [*table, cosim, floquet]:
        for m in re.finditer(r"FMI 2\.0(?! (?:or|and) 3\.0|/3\.0| in DIR)", text):
            raise AssertionError(f"FMI 2.0 only? {text[max(0, m.start() - 60):m.end() + 40]!r}")
    assert main(["floquet", "--plant", str(built_fmus3["DroneFlyFlapping"])]) == 0
    assert main(["cosim", "--system", str(built_fmus3["DroneFlyHover.ssp"]), "--stop", "2",
                 "--no-plot", "--out", str(tmp_path)]) == 0


def test_fmu_counts_in_the_docs_are_the_builds(built_fmus, built_fmus3):
    """docs/fmi3.md names the number of FMUs in FMUS and lists each; docs/compliance.md the
    number that `dronefly check` checks by default (every FMU that `dronefly build` writes:
    FMI 2.0 with the container FMU, and FMI 3.0)."""
    fmi3 = (DOCS / "fmi3.md").read_text(encoding="utf-8")
    m = re.search(r"(\w+) FMUs \(`dronefly\.harness\.builder\.build\.FMUS`\)", fmi3)
    assert m and _WORDS[m.group(1).lower()] == len(FMUS)
    listing = fmi3[:m.start()]
    assert all(f"{name}.fmu" in listing for name in FMUS), "the build listing misses an FMU"
    two = [p for p in built_fmus.values() if p.suffix == ".fmu"]
    three = [p for p in built_fmus3.values() if p.suffix == ".fmu"]
    assert len(three) == len(FMUS) and len(two) == len(FMUS) + 1  # + the container FMU
    text = " ".join((DOCS / "compliance.md").read_text(encoding="utf-8").split())
    assert (f"checks the project's {len(two) + len(three)} FMUs: {len(FMUS)} FMI 2.0 ones and "
            f"the container FMU, {len(three)} FMI 3.0 ones") in text


@pytest.mark.integration
def test_averaging_doc_prints_what_cosim_prints(built_fmus, tmp_path, monkeypatch, capsys):
    """docs/averaging.md's block after `dronefly cosim --system DroneFlyFlappingLateral.ssp
    --step 1` holds every line the command prints (the "no verdict" line included)."""
    from dronefly.harness.flapping import write_flapping_ssp

    monkeypatch.chdir(tmp_path)
    ssp = write_flapping_ssp(built_fmus["DroneFlyFlapping"].parent, "DroneFlyFlappingLateral.ssp")
    assert main(["cosim", "--system", str(ssp), "--step", "1", "--no-plot", "--out",
                 "coarse"]) == 0
    printed = capsys.readouterr().out.strip().splitlines()
    block = doc_block((DOCS / "averaging.md").read_text(encoding="utf-8"), "flapping:master-cli",
                      "docs/averaging.md").splitlines()
    # the command's lines (counts and names; no float among them), then the script's
    assert block[:len(printed)] == printed


def test_docs_say_what_is_measured_and_what_is_conjecture():
    """Sensing once per wing beat is Chang & Wang's (2014) conjecture, from simulations of
    fruit flies; the latencies are measured on fruit flies (about 1 mg); none is published for
    the drone fly, whose mass (the paper's Sect. 2.4) is quoted from the model's data."""
    latency = " ".join((DOCS / "latency.md").read_text(encoding="utf-8").split())
    averaging = " ".join((DOCS / "averaging.md").read_text(encoding="utf-8").split())
    readme = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    mg = FLIGHT_DATA["m_body"] * 1e6
    assert "Every latency above was measured on fruit flies (*Drosophila*, about 1 mg)" in latency
    assert ("No sensing latency of the drone fly (*Eristalis*; the paper's model insect has a "
            f"body mass of {mg:.2f} mg, Sect. 2.4") in latency
    assert "is a conjecture, not a measurement: Chang & Wang (2014) infer it" in latency
    assert "a conjecture of Chang & Wang 2014 from simulations of fruit flies" in averaging
    assert "as flies do" not in averaging
    assert "every latency of fruit flies** (none known for drone flies)" in readme
