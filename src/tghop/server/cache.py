"""The server's cache folders: model files named by id, the last used in memory, the folder
bounded by dropping the least recently used files (docs/serve.md, "Files and safety").

:class:`ModelCache` keeps one kind of file in one folder: TGHop models (``<cache>/models/<id>.npz``,
the default) or co-occurrence checkpoints (``<cache>/cooc/<id>.pt``, :mod:`tghop.server.cooc`).
An id is 64 hex digits (a content hash); anything else is 404 before the file system is asked.
"""

from __future__ import annotations

import errno
import hashlib
import os
import re
import tempfile
import threading
from collections import OrderedDict
from concurrent.futures import Future
from pathlib import Path

from .._errors import TGHopError, collect_warnings
from .requests import RequestError
from .safety import check_archive

__all__ = ["ModelCache", "FillStates", "DEFAULT_CACHE_BYTES", "ID"]

#: An id: 64 hex digits.
ID = re.compile(r"[0-9a-f]{64}\Z")
#: Fitted models kept in memory (the last used ones).
_LOADED = 4
#: Summaries kept (:meth:`ModelCache.summary`; a few KB each), the last used ones.
_SUMMARIES = 256
#: Where a file's path stood in a warning of reading it, kept (:meth:`ModelCache.notes` puts the upload's name there).
_PATH = "\x00"
#: What to do about a model the server does not have, in the page's words and the API's (0.62; 0.61: the API's alone,
#: "fit one with POST /api/models").
MODEL_HINT = "pick its exemplar again to fit it (the API: POST /api/models)"
#: Default bound of the cache folder: 2 GB (a model of the default settings is 10-40 MB).
DEFAULT_CACHE_BYTES = 2 * 1000**3


class FillStates:
    """Where the fills of one request's hole stand (0.61): fill k of a seed is the k-th drawn from one generator, as
    ``tghop inpaint --count`` draws them; kept here, the generator's state after each fill of the last
    :attr:`KEPT` requests (``key``: a hash of the model, the picture, its mask or growth, maps, seed and tile), so
    that fill k of a page's strip goes on from fill k - 1's, not from the seed again (each fill redrawn: k fills
    for the k-th). A state not kept is only slower: the fills before are drawn again."""

    #: States kept (a few hundred bytes each), the last used ones.
    KEPT = 64

    def __init__(self):
        self._states = OrderedDict()
        self._lock = threading.Lock()

    def after(self, key: str, k: int):
        """``(j, state)``: the latest fill ``j`` below ``k`` whose generator's state is kept, or ``(0, None)``."""
        with self._lock:
            for j in range(k - 1, 0, -1):
                state = self._states.get((key, j))
                if state is not None:
                    self._states.move_to_end((key, j))
                    return j, state
        return 0, None

    def keep(self, key: str, k: int, state: dict) -> None:
        """Keep the generator's ``state`` after fill ``k`` of ``key``."""
        with self._lock:
            self._states[(key, k)] = state
            self._states.move_to_end((key, k))
            while len(self._states) > self.KEPT:
                self._states.popitem(last=False)


def _load_model(path):
    """A texture model or a whole material (:mod:`tghop.server.materials`)."""
    from ..modelfile import load_model

    return load_model(path, material=True)


class ModelCache:
    """Model files named by id in ``<cache>/<folder>``, the last used models in memory; the
    folder kept under ``max_bytes`` (None: no bound) by dropping the least recently used
    files.

    Parameters
    ----------
    cache_dir : str or os.PathLike
    max_bytes : int or None
    folder, suffix : str
        The folder in ``cache_dir`` and the files' suffix (``models``, ``.npz``: TGHop models).
    load : callable, optional
        ``load(path)`` -> the model (default :func:`tghop.modelfile.load_model`).
    what, hint : str
        The kind of file and how to make one, in the 404 message.
    """

    def __init__(self, cache_dir, max_bytes: int | None = DEFAULT_CACHE_BYTES, *, folder: str = "models",
                 suffix: str = ".npz", load=None, what: str = "model", hint: str = MODEL_HINT):
        self.max_bytes = max_bytes
        self.suffix, self.what, self.hint = suffix, what, hint
        self._load = load or _load_model
        self.root = Path(cache_dir).expanduser()
        self.models = self.root / folder
        try:
            self.models.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise TGHopError(f"{self.models}: cannot create the cache folder ({exc.strerror}); "
                             "choose another with --cache") from None
        for stale in self.models.glob(".*.tmp"):  # left by a server killed while writing
            try:
                stale.unlink()
            except OSError:
                pass
        self._loaded = OrderedDict()
        self._summaries = OrderedDict()
        self._notes = OrderedDict()  # id -> what reading its file warned of (:meth:`notes`), the last read ones
        self._names = {}  # id -> the name of its upload, while its notes are kept (:meth:`model_notes`)
        self._fit_notes = OrderedDict()  # id -> what its fit here warned of (:meth:`fit_notes`), the last ones
        self._loading = {}  # id -> the Future of its load under way: callers asking meanwhile wait for it
        self._lock = threading.Lock()
        self.prune()  # the bound may be lower than the last server's

    def touch(self, model_id: str) -> None:
        """Mark the model's file as used now (what :meth:`prune` orders by)."""
        try:
            os.utime(self.path(model_id))
        except OSError:  # gone meanwhile: it is fitted again when asked for
            pass

    def size(self) -> int:
        """Bytes of the model files in the folder."""
        return sum(size for _, size, _ in self._files())

    def _files(self):
        out, n = [], len(self.suffix)
        try:
            entries = list(os.scandir(self.models))
        except OSError:  # the folder gone or unreadable: nothing to count or prune
            return out
        for entry in entries:
            if entry.name.endswith(self.suffix) and ID.match(entry.name[:-n]):
                try:
                    st = entry.stat()
                except OSError:
                    continue
                out.append((st.st_mtime, st.st_size, entry.name[:-n]))
        return out

    def prune(self, keep: str | None = None) -> list:
        """Remove the least recently used model files until the folder is within
        ``max_bytes`` (``keep``: an id never removed, the model just added); returns the
        ids removed."""
        if self.max_bytes is None:
            return []
        files = sorted(self._files())
        total = sum(size for _, size, _ in files)
        removed = []
        for _, size, model_id in files:
            if total <= self.max_bytes:
                break
            if model_id == keep:
                continue
            try:
                os.unlink(self.models / f"{model_id}{self.suffix}")
            except FileNotFoundError:
                pass
            except OSError:
                continue
            total -= size
            removed.append(model_id)
            with self._lock:
                self._loaded.pop(model_id, None)
                self._summaries.pop(model_id, None)
        return removed

    def store(self, content: bytes, filename: str, *, hint: str, wanted=None, refit=None) -> str:
        """Keep uploaded bytes under their SHA-256 once this cache's loader accepts them: the
        id. Not loadable: 400 (no room: 413), ``hint`` saying what to send; nothing is left
        in the folder either way. ``wanted()``, asked once the file is read and before it is kept: False
        (its client has gone) drops it, 499 (:meth:`tghop.server.core.Server.still_wanted`). ``refit(error)``:
        the words that stand for the command line's fix of a file the loader cannot use (a loader error's
        ``fix``, :func:`tghop.modelfile.load_model`'s "tghop fit EXEMPLAR -o PATH"), the page's own (0.62)."""
        if not content:
            raise RequestError(400, f"{filename} is empty; {hint}")
        check_archive(content, filename, self.what)  # a decompression bomb: refused before it is read
        key = hashlib.sha256(content).hexdigest()
        final = self.path(key)
        if final.is_file():
            self.touch(key)
            if self.notes(key, filename) is None:  # kept before and not read since: read now, for its notes
                self.load(key)
            self._name(key, filename)
            return key
        tmp = None
        try:
            try:
                fd, tmp = tempfile.mkstemp(prefix=f".upload-{key[:12]}.", suffix=".tmp", dir=self.models)
                with os.fdopen(fd, "wb") as fh:
                    fh.write(content)
            except OSError as exc:
                raise self._unwritable(exc) from None
            try:
                loaded = self._read_noting(key, tmp)
            except TGHopError as exc:
                fix, said = getattr(exc, "fix", None), str(exc)
                if refit is not None and fix:
                    said = said.replace(fix, refit(exc))
                raise RequestError(400, said.replace(tmp, filename)) from None
            except MemoryError:
                raise RequestError(413, f"{filename}: not enough memory to read this {self.what}") from None
            if wanted is not None and not wanted():
                raise RequestError(499, f"the client went away while {filename} was read; it was not kept")
            try:
                os.replace(tmp, final)
            except OSError as exc:
                raise self._unwritable(exc) from None
            tmp = None
        finally:
            if tmp is not None:
                try:
                    os.unlink(tmp)
                except OSError:
                    pass
        self.added(key, loaded)
        self._name(key, filename)
        return key

    def _name(self, model_id: str, filename: str) -> None:
        """The upload's name, for :meth:`model_notes` (kept as long as the file's notes are)."""
        with self._lock:
            if model_id in self._notes:
                self._names[model_id] = filename

    def _read_noting(self, model_id: str, path):
        """``self._load(path)``, what it warned of kept as the file's notes (:meth:`notes`) instead of issued
        (this thread's tghop warnings: :func:`tghop._errors.collect_warnings`)."""
        with collect_warnings() as said:
            model = self._load(path)
        with self._lock:
            self._notes[model_id] = [str(w).replace(str(path), _PATH) for w in said]
            self._notes.move_to_end(model_id)
            while len(self._notes) > _SUMMARIES:
                self._names.pop(self._notes.popitem(last=False)[0], None)
        return model

    def notes(self, model_id: str, name: str):
        """What reading the file of ``model_id`` warned of (a model made by a newer tghop, statistics of an old one
        not used), as the library said it, the file named ``name`` (an upload's); None when it has not been read
        since the server started (or was read too long ago)."""
        with self._lock:
            said = self._notes.get(model_id)
            if said is not None:
                self._notes.move_to_end(model_id)  # a model in use keeps its notes
        return None if said is None else [line.replace(_PATH, name) for line in said]

    def fitted(self, model_id: str, said) -> None:
        """Keep what the fit of ``model_id`` warned of (``said``: the fit's tghop warnings, a map named as a height
        map that holds colours, say), for :meth:`fit_notes`; the last :data:`_SUMMARIES` fits' are kept."""
        with self._lock:
            self._fit_notes.pop(model_id, None)
            if said:
                self._fit_notes[model_id] = [str(w) for w in said]
                while len(self._fit_notes) > _SUMMARIES:
                    self._fit_notes.popitem(last=False)

    def fit_notes(self, model_id: str) -> list:
        """What the fit of ``model_id`` in this server warned of (:meth:`fitted`; 0.58: 0.57's fit job let it go
        to the server's console, and the page said nothing), for its summary only: unlike a file's read warnings
        (:meth:`model_notes`), not repeated with each image, as ``tghop synth`` does not repeat ``tghop fit``'s."""
        with self._lock:
            return list(self._fit_notes.get(model_id, ()))

    def model_notes(self, model_id: str) -> list:
        """What reading the file of ``model_id`` warned of, for any answer that uses the model (a generation's
        warning header, its summary; 0.58: a file kept by an earlier server, read again at its first use, told
        nothing until it was uploaded again): :meth:`notes`, the file named as it was uploaded (as the upload's
        notes named it), else ``model <first 12 digits of the id>``; [] when it has not been read here."""
        with self._lock:
            name = self._names.get(model_id)
        return self.notes(model_id, name or f"{self.what} {model_id[:12]}") or []

    def _unwritable(self, exc: OSError) -> RequestError:
        """507 for a file the folder cannot take (a full disk, a folder made read-only or removed
        meanwhile): the server's trouble, said in one line, not the upload's; its fix is for whoever started the
        server, said as such to the page (0.63; 0.62 told the page "start the server with another --cache")."""
        return RequestError(507, f"cannot write to the cache folder {self.models} ({exc.strerror or exc}); the server "
                                 f"keeps no new {self.what} until whoever started it frees some space there or starts "
                                 "it again with another folder (tghop serve --cache FOLDER)")

    def cannot_keep(self) -> RequestError:
        """:meth:`_unwritable` of a fitted model's file that could not be written into the folder (0.63: 0.62's failed
        fit said the library's words, "... is a file, not a folder; give the model a path in a folder"): why, as a
        probe file in the folder finds it (the folder gone, or not one, or read-only), else a full disk."""
        try:
            fd, probe = tempfile.mkstemp(prefix=".probe.", suffix=".tmp", dir=self.models)
            os.close(fd)
            os.unlink(probe)
        except OSError as exc:
            return self._unwritable(exc)
        return self._unwritable(OSError(errno.ENOSPC, "the model's file could not be written: a full disk?"))

    def added(self, model_id: str, model) -> None:
        """A model file was just written: keep the model in memory and the folder in bounds."""
        self.remember(model_id, model)
        self.prune(keep=model_id)

    def path(self, model_id: str) -> Path:
        if not ID.match(model_id):
            raise RequestError(404, f"no {self.what} {model_id[:80]!r}; {self.hint}")
        return self.models / f"{model_id}{self.suffix}"

    def has(self, model_id: str) -> bool:
        return self.path(model_id).is_file()

    def remember(self, model_id: str, model) -> None:
        with self._lock:
            self._keep(model_id, model)

    def _keep(self, model_id: str, model) -> None:
        """``model`` in memory, the least recently used dropped (the lock held)."""
        self._loaded[model_id] = model
        self._loaded.move_to_end(model_id)
        while len(self._loaded) > _LOADED:
            self._loaded.popitem(last=False)

    def summary(self, model_id: str):
        """The summary kept for ``model_id`` (:meth:`keep_summary`), the file marked as used; None if none is
        kept; 404 when the file is gone (dropped by the bound, or by hand)."""
        path = self.path(model_id)
        with self._lock:
            known = self._summaries.get(model_id)
            if known is not None:
                self._summaries.move_to_end(model_id)
        if known is None:
            return None
        if not path.is_file():
            with self._lock:
                self._summaries.pop(model_id, None)
            raise self.missing(model_id)
        self.touch(model_id)
        return known

    def keep_summary(self, model_id: str, summary) -> None:
        """Keep ``summary`` of ``model_id`` (a file named by its content's hash never changes, nor does its
        summary): asked again, it is answered without loading the model. The last used are kept."""
        with self._lock:
            self._summaries[model_id] = summary
            self._summaries.move_to_end(model_id)
            while len(self._summaries) > _SUMMARIES:
                self._summaries.popitem(last=False)

    def missing(self, model_id: str) -> RequestError:
        """The 404 of a model (or checkpoint) that is not in the folder: never made, or dropped by the bound."""
        why = "never made here, or its fit has not ended, or" if self.what == "model" else "never uploaded, or"
        return RequestError(404, f"no {self.what} {model_id[:12]}... on the server ({why} its cache dropped it); "
                                 f"{self.hint}")

    def in_memory(self, model_id: str) -> tuple:
        """``(model, None)`` when ``model_id`` is in memory (its file marked as used), ``(None, future)`` while
        another caller reads it (:meth:`load`'s ``concurrent.futures.Future``: its model or its error), else
        ``(None, None)``: a caller reads it with :meth:`load`. Never reads a file (for the event loop)."""
        path = self.path(model_id)
        with self._lock:
            model = self._loaded.get(model_id)
            if model is None:
                return None, self._loading.get(model_id)
            self._loaded.move_to_end(model_id)
        if path.is_file():
            self.touch(model_id)
            return model, None
        with self._lock:  # removed by the bound (or by hand): as if never fitted
            self._loaded.pop(model_id, None)
        return None, None

    def load(self, model_id: str):
        """The fitted model (404 if there is none). Callers asking at once for a model not in memory share
        one load (each model's own: loads of different models do not wait for each other); a failed load's
        error reaches each of them, and the next call tries again. The server reads a model a generation
        needs in its turn of the decode gate, on a decoding thread (:meth:`tghop.server.core.Server.in_executor`;
        :meth:`in_memory` tells it whether a read is needed)."""
        path = self.path(model_id)
        while True:
            with self._lock:
                model = self._loaded.get(model_id)
                loading, first = None, False
                if model is not None:
                    self._loaded.move_to_end(model_id)
                else:
                    loading = self._loading.get(model_id)
                    first = loading is None
                    if first:
                        loading = self._loading[model_id] = Future()
            if model is None:
                break
            if path.is_file():
                self.touch(model_id)
                return model
            with self._lock:  # removed by the bound (or by hand): as if never fitted
                self._loaded.pop(model_id, None)
            # now not in memory: 404 unless the file is back meanwhile
        if not first:
            return loading.result()  # another caller's load: its model, or its error
        try:
            model = self._read(model_id, path)
        except BaseException as exc:
            with self._lock:
                del self._loading[model_id]
            loading.set_exception(exc)
            raise
        with self._lock:  # in memory as it stops being loaded: a caller now finds one or the other
            del self._loading[model_id]
            self._keep(model_id, model)
        loading.set_result(model)
        return model

    def _read(self, model_id: str, path: Path):
        """The model read from ``path`` (404 if it is not there, or dropped by the bound meanwhile)."""
        if not path.is_file():
            raise self.missing(model_id)
        try:
            model = self._read_noting(model_id, path)
        except TGHopError:
            if not path.is_file():  # dropped by the bound since (another model added meanwhile)
                raise self.missing(model_id) from None
            raise
        self.touch(model_id)
        return model
