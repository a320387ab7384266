"""A virtual environment with only the core install of dronefly-fmu (``pip install
dronefly-fmu`` without extras), or with only another distribution (``fmpy``), made in about a
second from this environment's packages.

The environment's site-packages gets a link to each installed file tree of every distribution
that ``dronefly-fmu``'s core requirements pull in (their requirements' markers evaluated without
an extra), nothing else: the optional packages of the extras (matplotlib, tqdm, threadpoolctl,
dask, libcosimpy) are truly absent there, as after ``pip install dronefly-fmu``, and no
download is needed. ``bin/`` has their console scripts (``dronefly``, ``fmpy``, ...) and
``python``.
"""

from __future__ import annotations

import subprocess
import sys
import sysconfig
from importlib import metadata
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

__all__ = ["OPTIONAL_MODULES", "core_distributions", "make_core_env"]

#: the top-level modules of the extras' packages (pyproject.toml), absent from the core install
OPTIONAL_MODULES = ("matplotlib", "tqdm", "threadpoolctl", "dask", "distributed", "libcosimpy")


def core_distributions(root: str = "dronefly-fmu") -> dict[str, metadata.Distribution]:
    """``root`` and every distribution its requirements need, extras only where a requirement
    asks for them (by canonical name)."""
    seen: dict[str, metadata.Distribution] = {}
    todo: list[tuple[str, tuple[str, ...]]] = [(root, ())]
    while todo:
        name, extras = todo.pop()
        key = canonicalize_name(name)
        if key in seen:
            continue
        # from the installed site-packages (the checkout's own dronefly_fmu.egg-info, on
        # sys.path when the tests run from it, lists the sources, not the install)
        site = sorted({sysconfig.get_paths()[k] for k in ("purelib", "platlib")})
        found = list(metadata.distributions(name=name, path=site))
        if not found:
            raise LookupError(f"{name} is not installed in {site}")
        seen[key] = dist = found[0]
        for text in dist.requires or []:
            req = Requirement(text)
            if req.marker is None or any(req.marker.evaluate({"extra": e})
                                         for e in ("", *extras)):
                todo.append((req.name, tuple(req.extras)))
    return seen


def make_core_env(env: Path, root: str = "dronefly-fmu") -> Path:
    """Make the environment of ``root``'s install (without extras) in ``env``; returns its
    ``bin`` folder."""
    env = env.resolve()
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(env)], check=True,
                   timeout=120)
    site = next((env / "lib").glob("python*/site-packages"))
    for dist in core_distributions(root).values():
        tops = {Path(str(f)).parts[0] for f in dist.files or () if not str(f).startswith("..")}
        for top in sorted(tops):  # packages, modules, .dist-info, .libs, the editable finder
            source = Path(str(dist.locate_file(top)))
            if source.exists() and not (site / top).exists():
                (site / top).symlink_to(source)
        for ep in dist.entry_points.select(group="console_scripts"):  # dronefly, fmpy, ...
            module, _, attr = ep.value.partition(":")
            script = env / "bin" / ep.name
            script.write_text(f"#!{env / 'bin' / 'python'}\nimport sys\n"
                              f"from {module} import {attr.split('.')[0]}\n"
                              f"sys.exit({attr.strip()}())\n")
            script.chmod(0o755)
    return env / "bin"
