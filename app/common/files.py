"""Files the application writes: atomically, with the provenance that makes a result traceable."""
from __future__ import annotations

import datetime
import os
import pathlib
import stat
import tempfile
from importlib.metadata import PackageNotFoundError, version

from handeye.app.common.errors import RequestError
from handeye.model.common import scratch


def tool_version():
    """Installed version of handeye (or 'unknown' when run from a source tree)."""
    try:
        return version("handeye")
    except PackageNotFoundError:
        return "unknown (source tree)"


def provenance(dataset, options):
    """Tool version, dataset path and hash, the options of the run and the time (UTC).

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
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


def input_files(dataset):
    """The files a dataset is read from (resolved, symlinks followed): never to be written over.

    Every CSV and TOML file of its folder and every profile it read, whatever its name.
    """
    files = {f.resolve() for f in pathlib.Path(dataset.path).rglob("*") if f.is_file() and f.suffix in (".csv", ".toml")}
    return files | {pathlib.Path(p).resolve() for p in getattr(dataset, "profile_files", ())}


#: Figure formats --plot writes (by the file's extension).
PLOT_FORMATS = ("png", "pdf", "svg", "jpg", "jpeg", "eps", "ps", "tif", "tiff", "webp")


def _same_file(a, b):
    try:
        return os.path.samefile(a, b)  # hard links and symlinks included
    except OSError:
        return False


def _writable(folder, option, path):
    try:
        with scratch.signals_held(), tempfile.NamedTemporaryFile(dir=folder, prefix=".handeye-probe.", delete=True):
            pass  # created and removed with the signals held back: an interruption leaves no probe
    except OSError as exc:
        raise RequestError(f"{option} {path}: cannot write in {folder}: {exc.strerror or exc}") from None


def _existing_folder(path, option):
    """The folder a file ``path`` goes into; RequestError naming ``option`` when it does not exist."""
    folder = pathlib.Path(path).parent
    if not folder.is_dir():
        raise RequestError(f"{option} {path}: folder {folder} does not exist")
    return folder


def check_output_path(path, option, inputs=(), plot=False):
    """Refuse, before any work, an output file that cannot be written or that is an input.

    The folder must exist and take a new file; the path must not be a folder, nor resolve
    (symlinks followed) to one of ``inputs``. Raises :class:`RequestError` naming ``option``.
    """
    target, folder = pathlib.Path(path), _existing_folder(path, option)
    if target.is_dir():
        raise RequestError(f"{option} {path}: is a folder; give a file name")
    if target.exists() and not target.is_file():
        raise RequestError(f"{option} {path}: is not a regular file (a device or a pipe); give a file name")
    if target.resolve() in {pathlib.Path(i).resolve() for i in inputs} or any(_same_file(target, i) for i in inputs):
        raise RequestError(f"{option} {path}: is a file this command reads; it would be overwritten -- choose another")
    if plot and target.suffix.lower().lstrip(".") not in PLOT_FORMATS:
        raise RequestError(f"{option} {path}: a figure needs one of the extensions {', '.join(PLOT_FORMATS)}")
    _writable(folder, option, path)
    return target


def check_output_folder(path, option, empty=False):
    """Refuse, before any work, an output folder that exists as a file, whose parent is missing,
    that cannot be written, or (``empty``) that holds files."""
    target = pathlib.Path(path)
    if target.exists() and not target.is_dir():
        raise RequestError(f"{option} {path}: exists and is not a folder")
    if target.is_dir():
        if empty and any(target.iterdir()):
            raise RequestError(f"{option} {path}: exists and is not an empty folder; choose a new one")
        _writable(target, option, path)
        return target
    _writable(_existing_folder(path, option), option, path)
    return target


def write_folder_atomically(folder, write, option="--out"):
    """``write(temporary folder)`` beside ``folder`` (new, or an empty folder), then rename it
    into place: an interrupted run (a signal, an error) leaves no half-written dataset, only
    what was there before (:mod:`handeye.model.common.scratch` removes the temporary folder). The
    folder gets the umask's mode, as ``mkdir`` would give it. Raises :class:`RequestError`."""
    target = pathlib.Path(folder)
    try:
        with scratch.temporary_folder(dir=target.parent, prefix=f".{target.name}.", ignore_cleanup_errors=True) as tmp:
            write(pathlib.Path(tmp))
            os.chmod(tmp, 0o777 & ~_umask())
            with scratch.signals_held():
                os.replace(tmp, target)  # over an empty folder too (POSIX rename)
    except OSError as exc:
        raise RequestError(f"{option} {folder}: cannot write: {exc.strerror or exc}") from None


def _umask():
    """The process's umask, read without changing it where ``/proc`` tells it."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)  # elsewhere: set and restore at once (the CLI runs no other thread here)
    os.umask(mask)
    return mask


def output_mode(target):
    """Permission bits of an output: a new file gets what the umask leaves of 0666 (0644 under
    umask 022, 0640 under 027), as ``open`` would give it; a file written over keeps its own."""
    try:
        st = os.stat(target)
    except OSError:
        return 0o666 & ~_umask()
    return stat.S_IMODE(st.st_mode) if stat.S_ISREG(st.st_mode) else 0o666 & ~_umask()


def _atomically(path, option, mode, write):
    """Call ``write(file)`` on a temporary file beside ``path``, then rename it over ``path``: never a
    half-written file, a hard link or an existing file replaced rather than written into, and the
    temporary file removed when anything fails or a signal ends the run (:mod:`handeye.model.common.scratch`).
    The file gets :func:`output_mode`'s permissions, not the temporary file's private 0600.
    Raises :class:`RequestError` naming ``option``."""
    target, folder = pathlib.Path(path), _existing_folder(path, option)
    name = None
    try:
        with scratch.signals_held():
            fh = tempfile.NamedTemporaryFile(mode, dir=folder, prefix=f".{target.name}.", suffix=".tmp", delete=False)
            name = fh.name
            scratch.register(name)
        with fh:
            write(fh)
            fh.flush()
            os.fchmod(fh.fileno(), output_mode(target))
            os.fsync(fh.fileno())
        with scratch.signals_held():
            os.replace(name, target)
            scratch.forget(name)
    except BaseException as exc:  # an error in write() or a KeyboardInterrupt as much as a full disk
        if name is not None and os.path.exists(name):
            os.unlink(name)  # never leave the temporary file behind
        if isinstance(exc, OSError):
            raise RequestError(f"{option} {path}: cannot write: {exc.strerror or exc}") from None
        raise
    finally:
        if name is not None:
            scratch.forget(name)


def write_text_atomically(path, text, option="--out"):
    """Write ``text`` to ``path`` through a temporary file and a rename (:func:`_atomically`)."""
    _atomically(path, option, "w", lambda fh: fh.write(text))


def save_figure_atomically(fig, path, option="--plot", dpi=120):
    """``fig.savefig`` through a temporary file and a rename, as every output (:func:`_atomically`).
    Figures are saved through :func:`handeye.app.present.figure_style.save`, which picks the dpi
    and checks the style first."""
    fmt = pathlib.Path(path).suffix.lower().lstrip(".") or "png"
    _atomically(path, option, "wb", lambda fh: fig.savefig(fh, format=fmt, dpi=dpi))


def write_stream_atomically(path, write, option="--out"):
    """``write(binary file)`` through a temporary file and a rename (:func:`_atomically`): large
    outputs stream without a copy in memory."""
    _atomically(path, option, "wb", write)


def write_bytes_atomically(path, data, option="--out"):
    """Bytes through a temporary file and a rename (:func:`_atomically`)."""
    _atomically(path, option, "wb", lambda fh: fh.write(data))
