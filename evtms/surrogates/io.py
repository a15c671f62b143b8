"""The mode-model file: save and load :class:`~evtms.system.mode_model.ModeModels` as a documented ``.npz``.

The layout is ``docs/surrogate-format.md``: plain NumPy arrays (no pickles),
per network ``net.<mode>.<head>.<field>`` with its layers, standardisation,
training range, feature and target names with units and activation, and
``attrs`` (JSON: evtms version, creation date, training scenarios and
metrics per mode). Loading checks every key, shape, value and name against
:mod:`evtms.system.mode_model`; anything wrong is one
:class:`~evtms.errors.EvtmsInputError` line naming the file and the problem.
Writing is atomic (a temporary file in the same folder, then
:func:`os.replace`).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import re
import tempfile
import zipfile
import zlib
from pathlib import Path

import numpy as np

import evtms
from evtms.errors import EvtmsInputError
from evtms.system import mode_model as mm

FORMAT = "evtms-mode-models"
FORMAT_VERSION = 1
#: Name of the model file in the output folder.
FILE_NAME = "mode_models.npz"
MODEL_FILE = FILE_NAME  # the name evtms.cli reads
#: Largest model file read [bytes].
MAX_FILE_BYTES = 200 * 1024 * 1024
#: Most bytes the arrays of a model file may take once inflated: evtms stores them uncompressed,
#: so a file it wrote never holds more than the file's own limit.
MAX_ARRAY_BYTES = MAX_FILE_BYTES
#: Most arrays a model file may hold (8 modes x 2 networks x (10 + 2 x 16 layers) + 4 = 676).
MAX_ARRAYS = 1000
#: Bytes inflated per read of an array.
_READ_BLOCK = 1 << 20
_VERSION = re.compile(r"^\d+\.\d+(\.\d+)?([.+-]?[0-9A-Za-z.+-]+)?$")
_HEAD_NAMES = {
    "power": (mm.POWER_FEATURES, mm.POWER_TARGETS),
    "dynamics": (mm.DYNAMICS_FEATURES, mm.DYNAMICS_TARGETS),
}
_CODE_NAMES = {code: name for name, code in mm.MODE_CODES.items()}


def _prefix(mode: str, head: str) -> str:
    return f"net.{mode}.{head}."


def network_arrays(mode: str, head: str, net: mm.Network) -> dict[str, np.ndarray]:
    """The file's arrays of one network (keys ``net.<mode>.<head>.<field>``)."""
    features, targets = _HEAD_NAMES[head]
    p = _prefix(mode, head)
    arrays = {
        p + "activation": np.array(net.activation),
        p + "n_layers": np.array(len(net.weights), np.int64),
        p + "features": np.array(features),
        p + "feature_units": np.array([mm.UNITS[f] for f in features]),
        p + "targets": np.array(targets),
        p + "target_units": np.array([mm.UNITS[t] for t in targets]),
    }
    for name in ("x_mean", "x_scale", "x_min", "x_max", "y_mean", "y_scale"):
        arrays[p + name] = np.asarray(getattr(net, name), np.float64)
    for k, (w, b) in enumerate(zip(net.weights, net.biases, strict=True)):
        arrays[p + f"W{k}"] = np.asarray(w, np.float64)
        arrays[p + f"b{k}"] = np.asarray(b, np.float64)
    return arrays


def save_mode_models(models: mm.ModeModels, path: str | Path) -> Path:
    """Write ``models`` to ``path`` atomically; returns the path.

    ``models.attrs`` must be JSON-serialisable; ``evtms_version``,
    ``created`` (UTC, ISO 8601) and ``format_version`` are set here.
    """
    path = Path(path)
    attrs = dict(models.attrs)
    attrs.setdefault("evtms_version", evtms.__version__)
    attrs.setdefault("created", _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat())
    attrs["format_version"] = FORMAT_VERSION
    codes = models.codes()
    modes = [_CODE_NAMES[c] for c in codes]
    arrays: dict[str, np.ndarray] = {
        "format": np.array(FORMAT),
        "format_version": np.array(FORMAT_VERSION, np.int64),
        "modes": np.array(modes, dtype="<U8") if modes else np.zeros(0, "<U8"),
        "attrs": np.array(json.dumps(attrs, sort_keys=True)),
    }
    for code, mode in zip(codes, modes, strict=True):
        arrays.update(network_arrays(mode, "power", models.power[code]))
        arrays.update(network_arrays(mode, "dynamics", models.dynamics[code]))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 -> the permissions a plain open() gives
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


class _Reader:
    """Checked access to the arrays of one file; every problem is one EvtmsInputError naming the file."""

    def __init__(self, path: Path, data: dict[str, np.ndarray]) -> None:
        self.path = path
        self.data = data

    def fail(self, what: str) -> EvtmsInputError:
        return EvtmsInputError(f"model file '{self.path}': {what}")

    def get(self, key: str) -> np.ndarray:
        if key not in self.data:
            raise self.fail(f"missing '{key}'")
        return self.data[key]

    def text(self, key: str) -> str:
        a = self.get(key)
        if a.dtype.kind != "U" or a.shape != ():
            raise self.fail(f"'{key}' is not a text value (dtype {a.dtype}, shape {a.shape})")
        return str(a)

    def names(self, key: str, expected: tuple[str, ...]) -> None:
        a = self.get(key)
        if a.dtype.kind != "U" or a.ndim != 1:
            raise self.fail(f"'{key}' is not a list of names (dtype {a.dtype}, shape {a.shape})")
        got = tuple(str(x) for x in a)
        if got != tuple(expected):
            diff = next((i for i, (g, e) in enumerate(zip(got, expected, strict=False)) if g != e), None)
            where = (
                f"position {diff}: {got[diff]!r} where evtms expects {expected[diff]!r}"
                if diff is not None
                else f"{len(got)} names where evtms expects {len(expected)}"
            )
            raise self.fail(f"'{key}' does not match evtms.system.mode_model ({where})")

    def floats(self, key: str, shape: tuple[int, ...]) -> np.ndarray:
        a = self.get(key)
        if a.dtype != np.float64:
            raise self.fail(f"'{key}' has dtype {a.dtype}; expected float64")
        if a.shape != shape:
            raise self.fail(f"'{key}' has shape {a.shape}; expected {shape}")
        if not np.all(np.isfinite(a)):
            raise self.fail(f"'{key}' holds non-finite values (NaN or inf)")
        return a


def _read_network(r: _Reader, mode: str, head: str) -> mm.Network:
    features, targets = _HEAD_NAMES[head]
    p = _prefix(mode, head)
    activation = r.text(p + "activation")
    if activation not in mm.ACTIVATIONS:
        raise r.fail(f"'{p}activation' is {activation!r}; allowed: {', '.join(mm.ACTIVATIONS)}")
    n_layers_a = r.get(p + "n_layers")
    if n_layers_a.dtype.kind not in "iu" or n_layers_a.shape != () or not 1 <= int(n_layers_a) <= 16:
        raise r.fail(f"'{p}n_layers' must be a whole number 1-16; got {n_layers_a!r}")
    n_layers = int(n_layers_a)
    r.names(p + "features", features)
    r.names(p + "feature_units", tuple(mm.UNITS[f] for f in features))
    r.names(p + "targets", targets)
    r.names(p + "target_units", tuple(mm.UNITS[t] for t in targets))
    n_in, n_out = len(features), len(targets)
    weights, biases = [], []
    width = n_in
    for k in range(n_layers):
        w = r.get(p + f"W{k}")
        if w.ndim != 2 or w.shape[0] != width:
            raise r.fail(f"'{p}W{k}' has shape {w.shape}; expected ({width}, n) after a layer of width {width}")
        if w.shape[1] > mm.MAX_WIDTH:
            raise r.fail(f"'{p}W{k}' has {w.shape[1]} units; allowed: at most {mm.MAX_WIDTH}")
        w = r.floats(p + f"W{k}", w.shape)
        width = w.shape[1]
        weights.append(w)
        biases.append(r.floats(p + f"b{k}", (width,)))
    if width != n_out:
        raise r.fail(f"'{p}W{n_layers - 1}' gives {width} outputs; expected {n_out} ({', '.join(targets)})")
    extra = [k for k in r.data if k.startswith(p) and re.fullmatch(r"[Wb]\d+", k[len(p) :])]
    if len(extra) != 2 * n_layers:
        raise r.fail(f"'{p}' holds {len(extra) // 2} layers' arrays; n_layers says {n_layers}")
    x = {n: r.floats(p + n, (n_in,)) for n in ("x_mean", "x_scale", "x_min", "x_max")}
    y = {n: r.floats(p + n, (n_out,)) for n in ("y_mean", "y_scale")}
    for n, a in (("x_scale", x["x_scale"]), ("y_scale", y["y_scale"])):
        if np.any(a <= 0):
            raise r.fail(f"'{p}{n}' holds values <= 0 (a scale must be positive)")
    if np.any(x["x_min"] > x["x_max"]):
        bad = features[int(np.argmax(x["x_min"] > x["x_max"]))]
        raise r.fail(f"'{p}x_min' exceeds '{p}x_max' for {bad}")
    return mm.Network(activation, weights, biases, **x, **y)


def _read_array(fp, where: str, info: zipfile.ZipInfo) -> np.ndarray:
    """One ``.npy`` member: its header checked against the member's declared size, then read in blocks."""
    fmt = np.lib.format
    version = fmt.read_magic(fp)
    if version not in ((1, 0), (2, 0)):
        raise EvtmsInputError(f"{where}: array {info.filename!r} is .npy version {version}; allowed: 1.0 or 2.0")
    read_header = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
    shape, fortran, dtype = read_header(fp)
    if dtype.hasobject:
        raise EvtmsInputError(f"{where}: array {info.filename!r} holds Python objects; allowed: numbers and text")
    count = math.prod(shape)
    nbytes = count * dtype.itemsize
    if any(n < 0 for n in shape) or nbytes > info.file_size:
        raise EvtmsInputError(
            f"{where}: array {info.filename!r} declares shape {shape} of {dtype} ({nbytes:,} bytes), "
            f"more than the {info.file_size:,} bytes of its member"
        )
    out = np.empty(count, dtype)
    view = memoryview(out.view(np.uint8)) if nbytes else memoryview(b"")
    done = 0
    while done < nbytes:
        n = fp.readinto(view[done : done + _READ_BLOCK])
        if not n:
            raise EvtmsInputError(f"{where}: array {info.filename!r} is truncated")
        done += n
    if fp.read(1):  # and at the member's end, zipfile checks its CRC
        raise EvtmsInputError(f"{where}: array {info.filename!r} holds more bytes than its header declares")
    return out.reshape(shape[::-1]).T if fortran else out.reshape(shape)


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """The arrays of ``.npz`` file ``path``, each one's size checked before it is inflated.

    A zip member says how large it inflates (``ZipInfo.file_size``) and its
    ``.npy`` header the shape and dtype: both are checked against
    :data:`MAX_ARRAY_BYTES` (for all arrays together) and against each other
    before anything is allocated, and no member is read beyond its declared
    size, so a small file that would inflate to gigabytes is refused.
    """
    where = f"model file '{path}'"
    data: dict[str, np.ndarray] = {}
    total = 0
    with zipfile.ZipFile(path) as zf:
        members = zf.infolist()
        if len(members) > MAX_ARRAYS:
            raise EvtmsInputError(f"{where} holds {len(members):,} members; allowed: at most {MAX_ARRAYS:,} arrays")
        for info in members:
            key = info.filename.removesuffix(".npy")
            if key == info.filename or key in data:
                what = "is not a .npy array" if key == info.filename else "is there twice"
                raise EvtmsInputError(f"{where}: member {info.filename[:80]!r} {what}; allowed: one .npy per array")
            total += info.file_size
            if total > MAX_ARRAY_BYTES:
                raise EvtmsInputError(
                    f"{where}: array {info.filename[:80]!r} inflates to {info.file_size:,} bytes, its arrays to "
                    f"{total:,} bytes at least; allowed: at most {MAX_ARRAY_BYTES:,} bytes of arrays"
                )
            with zf.open(info) as fp:
                data[key] = _read_array(fp, where, info)
    return data


def load_mode_models(path: str | Path) -> mm.ModeModels:
    """Read and check a mode-model file.

    Raises
    ------
    EvtmsInputError
        One line naming the file and what is wrong: not a readable ``.npz``
        (or one whose arrays would inflate beyond :data:`MAX_ARRAY_BYTES`,
        :func:`_read_npz`), another format or format version, a missing key, a wrong dtype or
        shape, non-finite weights, scales <= 0, feature or target names or
        units that differ from :mod:`evtms.system.mode_model`'s, an unknown
        mode, attributes that are not JSON or an evtms version that is not
        ``major.minor[.patch]``.
    """
    path = Path(path)
    if not path.is_file():
        raise EvtmsInputError(f"model file '{path}' does not exist or is not a file")
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise EvtmsInputError(f"model file '{path}' is {size:,} bytes; allowed: at most {MAX_FILE_BYTES:,}")
    try:
        data = _read_npz(path)
    except EvtmsInputError:
        raise
    except (OSError, ValueError, EOFError, RuntimeError, NotImplementedError, zipfile.BadZipFile, zlib.error) as exc:
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise EvtmsInputError(f"model file '{path}' is not a readable .npz file ({msg})") from None
    r = _Reader(path, data)
    if r.text("format") != FORMAT:
        raise r.fail(f"'format' is {r.text('format')!r}; expected {FORMAT!r}")
    fv = r.get("format_version")
    if fv.dtype.kind not in "iu" or fv.shape != () or int(fv) != FORMAT_VERSION:
        raise r.fail(f"'format_version' is {fv!r}; this evtms reads version {FORMAT_VERSION}")
    try:
        attrs = json.loads(r.text("attrs"))
    except json.JSONDecodeError as exc:
        raise r.fail(f"'attrs' is not valid JSON ({exc.msg} at {exc.pos})") from None
    if not isinstance(attrs, dict):
        raise r.fail("'attrs' is not a JSON object")
    for key in ("evtms_version", "created", "scenarios", "metrics"):
        if key not in attrs:
            raise r.fail(f"'attrs' misses '{key}'")
    version = attrs["evtms_version"]
    if not isinstance(version, str) or not _VERSION.match(version):
        raise r.fail(f"attrs evtms_version {version!r} is not a version (major.minor[.patch])")
    modes_a = r.get("modes")
    if modes_a.dtype.kind != "U" or modes_a.ndim != 1:
        raise r.fail(f"'modes' is not a list of names (dtype {modes_a.dtype}, shape {modes_a.shape})")
    modes = [str(m) for m in modes_a]
    if not modes:
        raise r.fail("'modes' is empty: the file holds no mode model")
    for m in modes:
        if m not in mm.MODE_CODES:
            raise r.fail(f"mode {m!r} is unknown; allowed: {', '.join(mm.MODE_CODES)}")
    if len(set(modes)) != len(modes):
        raise r.fail("'modes' lists a mode twice")
    power, dynamics = {}, {}
    for m in modes:
        code = mm.MODE_CODES[m]
        power[code] = _read_network(r, m, "power")
        dynamics[code] = _read_network(r, m, "dynamics")
    return mm.ModeModels(power=power, dynamics=dynamics, attrs=attrs)
