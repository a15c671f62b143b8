"""The LUT store (evtms/luts/store.py): the one place that knows where LUT and map files sit."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from evtms.luts.cache import CACHE_DIR_ENV
from evtms.luts.store import LutStore, cache_root

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def cache_dir(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv(CACHE_DIR_ENV, str(folder))
    return folder


# ---- the layout --------------------------------------------------------------------------------


def test_the_layout_of_a_folder(tmp_path, cache_dir):
    store = LutStore(tmp_path / "luts")
    assert store.lut("condenser") == tmp_path / "luts" / "condenser.nc"
    assert list(store.luts(["a", "b"]).values()) == [tmp_path / "luts" / "a.nc", tmp_path / "luts" / "b.nc"]
    assert store.map_file("ac") == tmp_path / "luts" / "maps" / "ac.nc"
    near, far = store.map_places("ac")
    assert near == store.map_file("ac") and far.parent.parent == cache_root() / "maps" and far.name == "ac.nc"
    assert LutStore.containing(store.lut("x")) == store
    assert LutStore.demo(tmp_path / "out", "cycle").folder == tmp_path / "out" / "luts" / "cycle"
    assert LutStore.places(tmp_path, "cycle") == (tmp_path, tmp_path / "cycle", tmp_path / "luts" / "cycle")
    store.maps_folder.mkdir(parents=True)
    for p in (store.lut("b"), store.lut("a"), store.map_file("m"), store.folder / "notes.txt"):
        p.write_text("x")
    assert store.files() == [store.lut("a"), store.lut("b"), store.map_file("m")]


def test_the_signature_follows_the_files(tmp_path):
    store = LutStore(tmp_path)
    store.lut("a").write_bytes(b"one")
    signature = store.signature(["a"])
    assert signature == {"a": {"file": "a.nc", "size": 3, "mtime_ns": os.stat(store.lut("a")).st_mtime_ns}}
    st = os.stat(store.lut("a"))
    os.utime(store.lut("a"), ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))  # touched: another signature
    assert store.signature(["a"]) != signature
    with pytest.raises(OSError):
        store.signature(["missing"])


# ---- one layout ------------------------------------------------------------------------------------

#: How a LUT folder's layout is spelled: a file joined as ``<name>.nc`` to a folder, the maps folder,
#: the demo's luts folder, a listing of a folder's LUT files.
_LAYOUT = re.compile(r'/ f"\{[^}]+\}\.nc"|/ "maps"|"luts" /|/ "luts"|\("luts", |glob\("\*\.nc"\)')


def test_the_folder_layout_is_spelled_only_in_the_store():
    found = []
    for path in sorted((ROOT / "evtms").rglob("*.py")):
        if path == ROOT / "evtms" / "luts" / "store.py":
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if _LAYOUT.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)
