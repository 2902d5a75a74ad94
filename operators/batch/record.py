"""What made each frame of a batch run: a fingerprint beside every frame, so that a resumed run
never ships a stale frame.

A frame range skips frames already complete (resume). "Complete" alone is not enough: a run
with another plate, combine, method, passes or extension version would skip every frame and
ship the old ones. So each frame's outputs get a record, the hidden JSON file
``OUT/.<output name>.vr.json`` written once its outputs are in place, holding the inputs that
made it (`inputs`: the plate file of that frame with its size, modification time and a hash
of its bytes, the shot file likewise, the Blender that rendered it, the effective reflection
and render settings, the passes, the view transform of PNG output, the extension's version)
and their SHA-256. The bytes are hashed (BLAKE2b, streamed) because a file replaced by one of
the same size with its time put back is another input; each file is hashed once per run
(`content_hash` keeps what it read while the file's size and time stay the same). A frame
is skipped only when its record matches this run's inputs; otherwise it is rendered again
and the report says why (`stale`: the names of the inputs that differ, the Blender that made
it, or that no record was found).

No bpy here: the batch gathers the inputs, this module compares and keeps them.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os

SUFFIX = ".vr.json"
RECORD_VERSION = 1


def record_path(output: str) -> str:
    """The hidden record of frame output ``output``: ``.<basename>.vr.json`` beside it."""
    folder, base = os.path.split(os.path.abspath(output))
    return os.path.join(folder, f".{base}{SUFFIX}")


_hashes = {}  # (path, device, inode, size, mtime_ns, ctime_ns) -> hex digest, for this run


def content_hash(path: str, st: os.stat_result | None = None) -> str:
    """BLAKE2b (16 bytes, hex) of the file ``path``, read in 1 MiB blocks; a file unchanged
    since it was last hashed in this process (same inode, size and times) is not read
    again. OSError when it cannot be read."""
    st = st or os.stat(path)
    key = (path, st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    found = _hashes.get(key)
    if found is None:
        h = hashlib.blake2b(digest_size=16)
        with open(path, "rb") as f:
            while block := f.read(1 << 20):
                h.update(block)
        found = _hashes[key] = h.hexdigest()
    return found


def file_identity(path: str) -> dict:
    """A file as an input: its absolute path, size, modification time (ns) and the hash of
    its bytes (`content_hash`); a file that is gone or unreadable is
    ``{"path": ..., "missing": True}``."""
    path = os.path.abspath(path)
    try:
        st = os.stat(path)
        content = content_hash(path, st)
    except OSError:
        return {"path": path, "missing": True}
    return {"path": path, "size": st.st_size, "mtime_ns": st.st_mtime_ns, "blake2b": content}


def digest(inputs: dict) -> str:
    """SHA-256 of ``inputs`` as canonical JSON (sorted keys)."""
    text = json.dumps(inputs, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def read(output: str) -> dict | None:
    """The record of ``output``, or None when there is none (or it is unreadable)."""
    try:
        with open(record_path(output), encoding="utf-8") as f:
            data = json.load(f)
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and "fingerprint" in data else None


def stale(output: str, inputs: dict) -> str | None:
    """None when ``output``'s record says ``inputs`` made it; else why not, in a few words
    ("no record of what made it", "made with another plate, combine", "made with Blender
    4.5.3" when only the Blender that rendered it differs)."""
    record = read(output)
    if record is None:
        return "no record of what made it"
    if record.get("fingerprint") == digest(inputs):
        return None
    before = record.get("inputs") if isinstance(record.get("inputs"), dict) else {}
    changed = sorted(k for k in set(before) | set(inputs) if before.get(k) != inputs.get(k))
    if changed == ["blender"]:
        return "made with " + _blender_name(before.get("blender"), inputs.get("blender"))
    return "made with another " + ", ".join(changed or ["set of inputs"])


def _blender_name(blender, now) -> str:
    """A record's Blender in a few words: "Blender 4.5.3" (with its build when only the
    build differs from ``now``'s), or "another Blender" when the record has none (written
    before the Blender was recorded)."""
    if not isinstance(blender, dict) or not blender.get("version"):
        return "another Blender"
    name = f"Blender {blender['version']}"
    if isinstance(now, dict) and now.get("version") == blender["version"]:
        name += f" (build {blender.get('build_hash') or 'unknown'})"
    return name


def write(output: str, inputs: dict) -> str:
    """Write ``output``'s record atomically (a temporary name, then renamed); returns the
    fingerprint. OSError when it cannot be written."""
    path = record_path(output)
    fingerprint = digest(inputs)
    temp = f"{path}.{os.getpid()}.tmp"
    try:
        with open(temp, "w", encoding="utf-8") as f:
            json.dump(
                {"version": RECORD_VERSION, "fingerprint": fingerprint, "inputs": inputs},
                f,
                indent=1,
                sort_keys=True,
                default=str,
            )
            f.write("\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(temp, path)
    finally:
        with contextlib.suppress(OSError):
            os.remove(temp)
    return fingerprint


def forget(output: str) -> None:
    """Remove ``output``'s record (before the frame is written again: a run killed half-way
    through the new outputs must not leave the old record vouching for them)."""
    with contextlib.suppress(FileNotFoundError):
        os.remove(record_path(output))
