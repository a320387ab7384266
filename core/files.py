"""Every result file is written next to its final name and then renamed: never half-written.

One mechanism (:func:`atomic_path`) for every writer of the project: text, CSV
tables, plots and reproducible zip archives (FMUs, SSP files), and one writer of a
co-simulation's CSV, PNG and JSON (:func:`write_run_files`).
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import os
import zipfile
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

import numpy as np

from .errors import DroneflyError

__all__ = ["OutputPathError", "atomic_path", "check_output_dir", "check_output_file",
           "format_cell", "run_name", "write_csv_atomic", "write_run_files", "write_text_atomic",
           "write_zip"]

#: Fixed timestamp of every archive entry, so that equal contents give equal bytes.
#: the signature of a zip archive's first local file header
_ZIP_MAGIC = b"PK\x03\x04"
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


class OutputPathError(DroneflyError):
    """An output path that cannot be written: found before any work."""


def _writable_folder(folder: Path, path: Path) -> None:
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(f"{str(path)!r}: the folder {str(folder)!r} is not writable")


def check_output_dir(path: str | Path) -> Path:
    """Check that ``path`` is a folder results can be written into, or can be made (its
    missing parents too), before any work; returns it.

    Raises
    ------
    OutputPathError
        ``path`` is a file, or its nearest existing ancestor is a file or not writable.
    """
    path = Path(path)
    if path.exists():
        if not path.is_dir():
            raise OutputPathError(f"{str(path)!r} is a file, not a folder")
        _writable_folder(path, path)
        return path
    ancestor = path.parent
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise OutputPathError(f"{str(path)!r}: {str(ancestor)!r} is a file, not a folder")
    _writable_folder(ancestor, path)
    return path


def check_output_file(path: str | Path) -> Path:
    """Check that the file ``path`` can be written (its folder exists and is writable, and it
    is not a folder) before any work; returns it.

    Raises
    ------
    OutputPathError
        ``path`` is a folder, or its folder does not exist, is a file or is not writable.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputPathError(f"{str(path)!r} is a folder; give the file to write")
    folder = path.parent
    if not folder.exists():
        raise OutputPathError(f"{str(path)!r}: the folder {str(folder)!r} does not exist")
    if not folder.is_dir():
        raise OutputPathError(f"{str(path)!r}: {str(folder)!r} is a file, not a folder")
    _writable_folder(folder, path)
    return path


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield ``path.part`` to write to; rename it to ``path`` if the block succeeds.

    On an exception the partial file is removed and ``path`` is left as it was; an ``OSError``
    on the temporary file is raised naming ``path``.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".part")
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(e, OSError) and str(tmp) in (e.filename, e.filename2):
            # the error names the file asked for, not its temporary name
            raise type(e)(e.errno, e.strerror, str(path)) from e
        raise


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically and return the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def format_cell(value: Any) -> str:
    """A CSV cell: floats with ``repr`` (they read back exactly), None as empty."""
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    if hasattr(value, "item"):  # numpy scalar
        return format_cell(value.item())
    return str(value)


def write_csv_atomic(path: str | Path, header: Sequence[str],
                     rows: Iterable[Sequence[Any] | Mapping[str, Any]], *,
                     quote_header: bool = False) -> Path:
    """Write a CSV table (header line, then one line per row) atomically.

    Rows are sequences in ``header`` order or mappings by column name; floats are
    written with ``repr``, so the file reads back to the same numbers. ``quote_header``
    quotes every column name (the FMI cross-check files' convention).
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    if quote_header:
        buf.write(",".join(f'"{h}"' for h in header) + "\n")
    else:
        w.writerow(header)
    for row in rows:
        cells = [row.get(c) for c in header] if isinstance(row, Mapping) else row
        w.writerow([format_cell(c) for c in cells])
    return write_text_atomic(path, buf.getvalue())


def run_name(stem: str, inputs: Mapping[str, Any]) -> str:
    """The files' name of a run: ``stem`` for a run with the defaults (``inputs`` empty),
    else ``stem_<8 hex digits>`` of a SHA-256 of the inputs that differ from them, so that
    runs with different inputs never write over each other's files in one folder (and the
    same inputs write the same name again)."""
    if not inputs:
        return stem
    text = json.dumps({k: inputs[k] for k in sorted(inputs)}, sort_keys=True, default=repr)
    return f"{stem}_{hashlib.sha256(text.encode('utf-8')).hexdigest()[:8]}"


def write_run_files(result: Any, out_dir: str | Path, name: str,
                    plot: Callable[[Any, Path], Any] | None = None) -> None:
    """Write a co-simulation's ``name.csv``, ``name.png`` and ``name.json`` into ``out_dir``.

    Each file is written next to its final name and all are renamed together once all are
    written (on an error none is left, half-written or not).

    Parameters
    ----------
    result : object
        A result with ``run`` (a ``LoopRun``: ``time`` [s], ``names``, ``signals``),
        ``to_json()`` and the attributes ``csv`` and ``plot``, which are set to the paths
        written before ``to_json()`` is called (the JSON names them; its ``units``, the unit
        of every CSV column, is where a reader of the CSV finds them).
    out_dir : path
        The folder (made if missing).
    name : str
        The files' name without suffix.
    plot : callable, optional
        ``plot(result, path)`` writes the PNG to ``path``; None writes no PNG.
    """

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    run = result.run
    with contextlib.ExitStack() as stack:
        csv_path = out / f"{name}.csv"
        write_csv_atomic(stack.enter_context(atomic_path(csv_path)), ["time", *run.names],
                         np.column_stack([run.time, run.signals]).tolist())
        result.csv = csv_path
        if plot is not None:
            png = out / f"{name}.png"
            plot(result, stack.enter_context(atomic_path(png)))
            result.plot = png
        summary = out / f"{name}.json"
        stack.enter_context(atomic_path(summary)).write_text(
            json.dumps(result.to_json(), indent=2, default=format_cell) + "\n", encoding="utf-8")


def write_zip(target: str | Path, files: Mapping[str, bytes]) -> Path:
    """Write a reproducible archive (sorted entries, fixed timestamps) atomically.

    Members are deflated, except members that are themselves zip archives (the FMUs of an SSP
    or of a container FMU): their data is compressed already, so they are stored.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(target) as tmp, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for rel in sorted(files):
            data = files[rel]
            info = zipfile.ZipInfo(rel, date_time=_ZIP_DATE)
            info.external_attr = 0o644 << 16
            info.compress_type = (zipfile.ZIP_STORED if data[:4] == _ZIP_MAGIC
                                  else zipfile.ZIP_DEFLATED)
            z.writestr(info, data, compresslevel=1)  # fast: builds are many in tests
    return target
