"""Files the application writes: atomically, with the provenance that makes a result traceable."""
from __future__ import annotations

import datetime
import json
import os
import pathlib
import tempfile

from handeye.app.errors import RequestError


def tool_version():
    """Installed version of handeye (or 'unknown' when run from a source tree)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("handeye")
    except PackageNotFoundError:
        return "unknown (source tree)"


def provenance(dataset, options):
    """Tool version, dataset path and hash, the options of the run and the time (UTC).

    Parameters
    ----------
    dataset : handeye.model.dataset.Dataset
    options : dict
        The options the result was made with (JSON-ready values).
    """
    return {
        "tool": "handeye",
        "version": tool_version(),
        "dataset_path": str(dataset.path),
        "dataset_sha256": dataset.content_hash(),
        "options": dict(options),
        "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }


def check_output_path(path, option):
    """Refuse, before any work, an output file whose folder does not exist or that is a folder.

    Raises :class:`RequestError` naming ``option``.
    """
    target = pathlib.Path(path)
    folder = target.parent if str(target.parent) else pathlib.Path(".")
    if not folder.is_dir():
        raise RequestError(f"{option} {path}: folder {folder} does not exist")
    if target.is_dir():
        raise RequestError(f"{option} {path}: is a folder; give a file name")
    return target


def check_output_folder(path, option):
    """Refuse, before any work, an output folder that exists as a file or whose parent is missing."""
    target = pathlib.Path(path)
    if target.exists() and not target.is_dir():
        raise RequestError(f"{option} {path}: exists and is not a folder")
    if not target.exists() and not (target.parent if str(target.parent) else pathlib.Path(".")).is_dir():
        raise RequestError(f"{option} {path}: folder {target.parent} does not exist")
    return target


def write_text_atomically(path, text, option="--out"):
    """Write ``text`` to ``path`` through a temporary file and a rename: never a half-written file.

    Raises :class:`RequestError` naming ``option`` when the folder does not exist.
    """
    target = pathlib.Path(path)
    folder = target.parent if str(target.parent) else pathlib.Path(".")
    if not folder.is_dir():
        raise RequestError(f"{option} {path}: folder {folder} does not exist")
    with tempfile.NamedTemporaryFile("w", dir=folder, prefix=f".{target.name}.", suffix=".tmp", delete=False) as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(fh.name, target)


def write_json_atomically(path, data, option="--out"):
    """JSON through :func:`write_text_atomically`."""
    write_text_atomically(path, json.dumps(data, indent=1), option=option)
