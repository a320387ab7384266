"""What CI provides and a local machine may lack: the files beside the checkout
(``../shared``: the paper's text, the Reference-FMUs and their results, the OMSimulator build)
and the tools .ci/setup-c-host.sh installs (gcc, a shared libpython, valgrind).

Locally a missing one skips its tests with the reason. On CI (``CI=true``, set by every CI
service and by .ci/run) the layout provides them, so a missing one is an error: a test that
skipped there would hide a failure.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import pytest

__all__ = ["ON_CI", "edited_copy", "need_shared", "provided_on_ci"]

#: GitHub Actions, GitLab CI and the others set CI=true
ON_CI = os.environ.get("CI", "").lower() in ("true", "1", "yes")


def need_shared(path: Path, what: str) -> None:
    """Skip (locally) or fail (on CI) when ``path`` under ``../shared`` is missing."""
    if path.exists():
        return
    why = f"{what}: not beside the checkout ({path})"
    if ON_CI:
        pytest.fail(f"{why}: the CI layout provides ../shared", pytrace=False)
    pytest.skip(why)


def provided_on_ci(why: str) -> None:
    """Something CI provides is missing here: fail on CI, skip (with ``why``) elsewhere."""
    if ON_CI:
        pytest.fail(f"{why}: CI provides it (.ci/setup-c-host.sh)", pytrace=False)
    pytest.skip(why)


def edited_copy(source: Path, path: Path, edits=(), drop: str = "", every: bool = False) -> Path:
    """A copy at ``path`` of the FMU archive ``source`` (a Reference-FMU, say) whose
    modelDescription.xml has ``edits`` (old, new) made, each ``old`` required to be there (every
    occurrence replaced if ``every``, else the first), and without the members whose names start
    with ``drop``: a description that no longer tells the truth about the unchanged binary."""
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(path, "w") as zout:
        for item in zin.infolist():
            if drop and item.filename.startswith(drop):
                continue
            data = zin.read(item)
            if item.filename == "modelDescription.xml" and edits:
                text = data.decode()
                for old, new in edits:
                    assert old in text, old
                    text = text.replace(old, new, -1 if every else 1)
                data = text.encode()
            zout.writestr(item, data)
    return path
