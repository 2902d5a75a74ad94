"""Render a shot on a Dask distributed cluster: frame chunks fanned out to the workers, each
chunk one run of the batch entry (render_shot.py) as a subprocess, per-chunk reports merged.

    python -m pipeline.farm --scheduler tcp://host:8786 shot.blend --plate PLATE --out DIR \
        --frames 1-240 --chunk 10 [--blender /path/to/blender | --bpy] [-- render_shot args]

No bpy here, and nothing Blender-specific on the driver: a worker runs either a Blender binary
(`blender -b shot.blend --python <extension>/render_shot.py -- ...`) or, with `--bpy`, its own
Python with the bpy module (`python -m render_shot shot.blend ...` in the extension folder).
The shot, the plate(s), OUT and the extension folder must be on shared storage mounted at the
same path on every worker and on the driver (which writes the merged report into OUT).

Frames land in OUT as render_shot names them (`<name>.<frame:04d>.<ext>`), each chunk its own
frames, written atomically by render_shot. Each chunk's report goes to a private temporary file
on its worker (`--report`), never to the shared OUT/<name>.report.json, which only the driver
writes: the merged report, atomically. render_shot skips frames that are already complete, so
re-running after a failure renders only what is missing. Chunks that crash or lose their worker
are retried (Dask `retries`); bad input (render_shot's exit code 2) is not.
Bad input: one line on stderr and exit code 2 (1 for a chunk that kept failing).
"""

import argparse
import contextlib
import importlib.util
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

EXIT_BAD_INPUT = 2
EXTENSION = Path(__file__).resolve().parents[1]  # the extension folder (holds render_shot.py)
WORKER_PYTHON = "{python}"  # in a command prefix: the worker's own interpreter (sys.executable)
# Options the driver sets per chunk; passing them through `-- ...` would break the fan-out.
OWNED_OPTIONS = ("--frames", "--frame", "--out", "--plate", "--report")


class ChunkError(RuntimeError):
    """A chunk's batch run failed. `returncode` 2 is bad input (the same on every worker)."""

    def __init__(self, message, returncode=None, frames=None):
        super().__init__(message)  # pickles as (message,) + __dict__: survives the trip back
        self.returncode = returncode
        self.frames = frames


class FarmError(RuntimeError):
    """A farm run stopped: the first failed chunk's frames and its one-line reason.
    `bad_input`: render_shot refused the chunk's input (exit code 2)."""

    def __init__(self, message, bad_input=False):
        super().__init__(message)
        self.bad_input = bad_input


# -- frames ----------------------------------------------------------------------------------


def _load_frames_module():
    """virtual_reflections/frames.py, the one home of the ``--frames`` grammar, loaded by path:
    importing the engine package would need NumPy and OpenImageIO on the driver."""
    name = "vr_frames"
    if name not in sys.modules:
        path = EXTENSION / "virtual_reflections" / "frames.py"
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        sys.modules[name] = module
    return sys.modules[name]


_frames = _load_frames_module()
FRAMES_HELP = _frames.FRAMES_HELP


def parse_frames(frames):
    """`"1-240"`, `"1-10x2"`, `"5"`, `"1,3,7-9"`, an int or an iterable of ints -> the sorted
    distinct frame numbers. Raises ValueError naming the bad part (render_shot's grammar)."""
    if isinstance(frames, int):
        return [frames]
    if not isinstance(frames, str):
        out = sorted({int(f) for f in frames})
        if not out:
            raise ValueError("no frames")
        return out
    return _frames.parse_frames(frames)


def format_frames(frames):
    """Sorted distinct frames -> the shortest spec in render_shot's `--frames` grammar:
    runs of consecutive frames as `a-b`, even strides of 3+ frames as `a-bxk`, else single."""
    frames = sorted(set(frames))
    parts, i = [], 0
    while i < len(frames):
        j = i
        if i + 1 < len(frames):
            step = frames[i + 1] - frames[i]
            while j + 1 < len(frames) and frames[j + 1] - frames[j] == step:
                j += 1
            if step == 1 and j > i:
                parts.append(f"{frames[i]}-{frames[j]}")
            elif j - i >= 2:
                parts.append(f"{frames[i]}-{frames[j]}x{step}")
            else:
                j = i
        if j == i:
            parts.append(str(frames[i]))
        i = j + 1
    return ",".join(parts)


def plan_chunks(frames, chunk_size):
    """The frames (a spec or ints) in chunks of `chunk_size` consecutive entries, in order, each
    as a `--frames` spec: `plan_chunks("1-10", 4) == ["1-4", "5-8", "9-10"]`."""
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
        raise ValueError(f"chunk size must be a positive whole number, not {chunk_size!r}")
    frames = parse_frames(frames)
    return [format_frames(frames[i : i + chunk_size]) for i in range(0, len(frames), chunk_size)]


# -- one chunk, on a worker ------------------------------------------------------------------


def batch_command(shot=None, blender=None, extension=EXTENSION):
    """The batch entry's command up to its own options, and the folder to run it in.

    With `blender` (a path valid on every worker): `blender -b SHOT --python-exit-code 1
    --python <ext>/render_shot.py --` (Blender returns 0 after a Python error without it).
    Without: the worker's own Python with the bpy module, `python -m render_shot` in the
    extension folder (the shot is then render_shot's positional argument)."""
    extension = str(extension)
    if blender:
        if shot is None:
            raise ValueError("a Blender binary needs the shot in its command line")
        script = os.path.join(extension, "render_shot.py")
        command = [blender, "-b", str(shot), "--python-exit-code", "1", "--python", script, "--"]
        return command, extension
    return [WORKER_PYTHON, "-m", "render_shot"], extension


def _reason(stderr, stdout, returncode):
    """The one line that says why a run failed."""
    lines = [x.strip() for x in (stderr or "").splitlines() if x.strip()]
    errors = [x for x in lines if x.startswith("render_shot: error")]
    if errors:
        return errors[-1]
    if lines:
        return lines[-1]
    if returncode is not None and returncode < 0:
        return f"killed by signal {-returncode}"
    tail = [x.strip() for x in (stdout or "").splitlines() if x.strip()]
    return tail[-1] if tail else f"exit code {returncode}"


def frame_entries(report):
    """A render_shot report (dict with a `frames` list, or the list itself) -> its per-frame
    entries, each a dict with at least `frame`."""
    entries = report.get("frames", []) if isinstance(report, dict) else report
    if not isinstance(entries, list) or not all(
        isinstance(e, dict) and "frame" in e for e in entries
    ):
        raise ValueError("report has no per-frame entries")
    return entries


def render_chunk(
    command_prefix, shot, plate, out, frames, extra_args=(), *, cwd=None, report=None, timeout=None
):
    """Run the batch entry for `frames` (a `--frames` spec) and return its per-frame report
    entries (dicts with `frame`, as render_shot writes them), in frame order.

    `command_prefix`: e.g. `[sys.executable, "-m", "render_shot"]` with `cwd` the extension
    folder, or `["blender", "-b", shot, "--python", ".../render_shot.py", "--"]`; the element
    `"{python}"` stands for this process's interpreter. The shot is appended as render_shot's
    positional argument unless the prefix already names it. `report`: where the chunk's report
    goes (`--report`, kept); by default a private temporary file, read and removed, so that
    concurrent chunks never share a report. Raises ChunkError with render_shot's one stderr
    line and its exit code when the run fails (or with the timeout)."""
    return frame_entries(
        run_chunk(
            command_prefix,
            shot,
            plate,
            out,
            frames,
            extra_args,
            cwd=cwd,
            report=report,
            timeout=timeout,
        )
    )


def run_chunk(
    command_prefix, shot, plate, out, frames, extra_args=(), *, cwd=None, report=None, timeout=None
):
    """render_chunk's work; returns the chunk's whole report (top-level fields and `frames`,
    the latter restricted to this chunk's frames)."""
    prefix = [sys.executable if a == WORKER_PYTHON else str(a) for a in command_prefix]
    command = [*prefix]
    if str(shot) not in prefix:
        command.append(str(shot))
    command += ["--plate", str(plate), "--out", str(out), "--frames", str(frames)]
    with tempfile.TemporaryDirectory(prefix="vr-farm-") as private:
        path = report or os.path.join(private, "chunk.report.json")
        command += ["--report", str(path), *map(str, extra_args)]
        try:
            run = subprocess.run(
                command,
                cwd=cwd,
                capture_output=True,
                text=True,
                timeout=timeout,
                stdin=subprocess.DEVNULL,
            )
        except subprocess.TimeoutExpired as exc:
            raise ChunkError(f"frames {frames}: no answer after {timeout} s", None, frames) from exc
        except OSError as exc:  # the binary is missing on this worker
            raise ChunkError(f"cannot run {command[0]}: {exc.strerror}", None, frames) from exc
        if run.returncode != 0:
            raise ChunkError(
                _reason(run.stderr, run.stdout, run.returncode), run.returncode, frames
            )
        try:
            with open(path, encoding="utf-8") as f:
                data = json.load(f)
            entries = frame_entries(data)
        except (OSError, ValueError) as exc:
            raise ChunkError(f"frames {frames}: no readable report: {exc}", 0, frames) from exc
    wanted = set(parse_frames(frames))
    data = dict(data) if isinstance(data, dict) else {}
    data["frames"] = sorted((e for e in entries if e["frame"] in wanted), key=lambda e: e["frame"])
    return data


def _name(shot, extra_args):
    """render_shot's output stem: `--name` if given, else the shot file's stem."""
    args = list(map(str, extra_args))
    for i, a in enumerate(args):
        if a == "--name" and i + 1 < len(args):
            return args[i + 1]
        if a.startswith("--name="):
            return a.split("=", 1)[1]
    return Path(str(shot)).stem


def _chunk_task(command_prefix, shot, plate, out, frames, extra_args, cwd, timeout):
    """What a worker runs: one chunk, timed. Bad input is returned, not raised, so that Dask
    does not retry what would fail the same on every worker; crashes raise (and are retried)."""
    started = time.perf_counter()
    host = socket.gethostname()
    try:
        from distributed import get_worker

        worker = get_worker().address
    except (ImportError, ValueError):  # called outside a Dask worker
        worker = None
    try:
        report = run_chunk(
            command_prefix, shot, plate, out, frames, extra_args, cwd=cwd, timeout=timeout
        )
    except ChunkError as exc:
        if exc.returncode != EXIT_BAD_INPUT:
            raise
        return {"frames": frames, "host": host, "error": str(exc), "bad_input": True}
    seconds = round(time.perf_counter() - started, 3)
    return {"frames": frames, "host": host, "worker": worker, "seconds": seconds, "report": report}


# -- the driver ------------------------------------------------------------------------------


def write_json_atomic(path, data):
    """Write JSON under a temporary name beside `path` and rename it into place: readers see
    the old file or the new one, never half of it."""
    folder, base = os.path.split(os.path.abspath(path))
    tmp = os.path.join(folder, f".{base}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        with open(tmp, "x", encoding="utf-8") as f:
            json.dump(data, f, indent=1)
            f.write("\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def merge_reports(reports, requested=None, previous=None, wall_seconds=None):
    """Chunk reports (render_shot's JSON) -> one report for the whole range.

    The first chunk's header (shot, plate, render settings); `frames` sorted by frame number
    (a later report wins for a frame that appears twice); every chunk's `warnings` once;
    `totals` over all frames, as render_shot counts them; `complete` when every chunk was and
    no requested frame is missing. `requested`: the whole range's spec. `previous`: the frames
    of an earlier merged report, whose entries a skipped frame keeps (as render_shot does with
    its own report when it resumes)."""
    merged, by_frame, warnings = {}, {}, []
    for report in reports:
        for key, value in report.items():
            merged.setdefault(key, value)
        for warning in report.get("warnings", ()):
            if warning not in warnings:
                warnings.append(warning)
        for entry in frame_entries(report):
            frame = entry["frame"]
            if entry.get("status") == "skipped" and frame in (previous or {}):
                entry = {**previous[frame], "status": "skipped"}
            by_frame[frame] = entry
    entries = [by_frame[f] for f in sorted(by_frame)]
    merged["frames"] = entries
    merged["warnings"] = warnings
    rendered = [e for e in entries if e.get("status") == "rendered"]
    seconds = {}
    for entry in rendered:
        for stage, value in (entry.get("times") or {}).items():
            seconds[stage] = round(seconds.get(stage, 0.0) + value, 4)
    merged["totals"] = {
        "frames": len(entries),
        "rendered": len(rendered),
        "skipped": sum(e.get("status") == "skipped" for e in entries),
        "warnings": sum(len(e.get("warnings") or ()) for e in entries),
        "seconds": seconds,
        "wall_seconds": None if wall_seconds is None else round(wall_seconds, 3),
    }
    complete = all(r.get("complete", True) for r in reports)
    if requested is not None:
        merged["requested"] = requested
        complete = complete and set(by_frame) >= set(parse_frames(requested))
    merged["complete"] = complete
    return merged


def read_report(path):
    """An earlier report's entries by frame number, or {} (missing or unreadable)."""
    try:
        with open(path, encoding="utf-8") as f:
            return {e["frame"]: e for e in frame_entries(json.load(f))}
    except (OSError, ValueError, TypeError, AttributeError):
        return {}


def _validate_extra(extra_args):
    for a in map(str, extra_args):
        option = a.split("=", 1)[0]
        if option in OWNED_OPTIONS:
            raise ValueError(f"{option} is set by the farm for each chunk; leave it out")
        # Abbreviations too: a render_shot with argparse's prefix matching took `--ou` for `--out`.
        owned = [o for o in OWNED_OPTIONS if len(option) > 2 and o.startswith(option)]
        if option.startswith("--") and owned:
            raise ValueError(
                f"{option} is an abbreviation of {' or '.join(owned)}, which the farm sets for "
                "each chunk; leave it out"
            )


def run_farm(
    scheduler,
    shot,
    plate,
    out,
    frames,
    chunk_size=10,
    *,
    blender=None,
    command_prefix=None,
    cwd=None,
    extra_args=(),
    retries=2,
    timeout=None,
    log=print,
):
    """Render `frames` of `shot` on a Dask cluster in chunks of `chunk_size` frames and merge
    the chunk reports into OUT/<name>.report.json (atomic write). Returns the merged report,
    whose `farm` field lists the chunks with the host and time each took.

    `scheduler`: an address (`tcp://host:8786`) or a `distributed.Client`. The batch entry is
    `blender` (a Blender binary, same path on every worker) or by default the worker's own
    Python with the bpy module; `command_prefix` and `cwd` override both (see render_chunk).
    `retries`: how often Dask re-runs a chunk that crashed, timed out or lost its worker (bad
    input is not retried: it would fail the same everywhere). `timeout`: seconds per chunk.
    Paths are made absolute here and must be valid on every worker (shared storage).
    The first failure cancels the chunks not yet started and raises FarmError; frames already
    written stay (a re-run skips them) and the merged report holds what finished, with
    `farm.failed` naming the chunk. `log`: called with each progress line (None: quiet)."""
    from distributed import Client

    started = time.perf_counter()
    shot, plate, out = (os.path.abspath(str(p)) for p in (shot, plate, out))
    extra_args = [str(a) for a in extra_args]
    _validate_extra(extra_args)
    chunks = plan_chunks(frames, chunk_size)
    if command_prefix is None:
        command_prefix, default_cwd = batch_command(shot, blender)
        cwd = cwd or default_cwd
    name = _name(shot, extra_args)
    os.makedirs(out, exist_ok=True)
    stamp = lambda: f"[{time.perf_counter() - started:7.1f} s]"  # noqa: E731
    log = log or (lambda line: None)

    client = scheduler if isinstance(scheduler, Client) else Client(scheduler, timeout="20s")
    try:
        with _code_by_value():
            workers = len(client.scheduler_info().get("workers", {}))
            log(
                f"{stamp()} {name}: {len(chunks)} chunk(s) of up to {chunk_size} frame(s), "
                f"{workers} worker(s) now"
            )
            task = (command_prefix, shot, plate, out, extra_args, cwd, timeout)
            futures = _submit_chunks(client, chunks, task, name, retries)
            results, failure = _collect(client, futures, len(chunks), log, stamp)
    finally:
        address = getattr(getattr(client, "scheduler", None), "address", None) or str(scheduler)
        if client is not scheduler:
            client.close()

    path = os.path.join(out, name + ".report.json")
    farm = {"scheduler": address, "chunk_size": chunk_size, "retries": retries}
    report = _merged_report(results, failure, frames, path, started, farm)
    if failure:
        raise FarmError(f"frames {failure['frames']}: {failure['error']}", failure["bad_input"])
    log(f"{stamp()} {len(report['frames'])} frame(s) done; report {path}")
    return report


@contextlib.contextmanager
def _code_by_value():
    """Ship this module's code with the tasks while inside: the workers need `distributed`,
    not this checkout on their sys.path (run as __main__, cloudpickle sends it by value
    anyway); the frames grammar too: a worker has no vr_frames module to import."""
    import cloudpickle

    module = sys.modules[__name__]
    by_value = (
        __name__ != "__main__" and __name__ not in cloudpickle.list_registry_pickle_by_value()
    )
    frames_by_value = _frames.__name__ not in cloudpickle.list_registry_pickle_by_value()
    try:
        if by_value:
            cloudpickle.register_pickle_by_value(module)
        if frames_by_value:
            cloudpickle.register_pickle_by_value(_frames)
        yield
    finally:
        if by_value:
            cloudpickle.unregister_pickle_by_value(module)
        if frames_by_value:
            cloudpickle.unregister_pickle_by_value(_frames)


def _submit_chunks(client, chunks, task, name, retries) -> dict:
    """Submit one `_chunk_task` per chunk of ``chunks`` with the arguments ``task``
    (command_prefix, shot, plate, out, extra_args, cwd, timeout), each under a key unique to
    this run, re-run up to ``retries`` times. Returns {future: its chunk}."""
    command_prefix, shot, plate, out, extra_args, cwd, timeout = task
    futures = {}
    run_id = uuid.uuid4().hex[:8]
    for spec in chunks:
        future = client.submit(
            _chunk_task,
            command_prefix,
            shot,
            plate,
            out,
            spec,
            extra_args,
            cwd,
            timeout,
            key=f"render_shot-{name}-{spec}-{run_id}",
            retries=retries,
            pure=False,
        )
        futures[future] = spec
    return futures


def _collect(client, futures, count, log, stamp):
    """The chunks' results as they finish, each logged; the first failure (a crash after its
    retries, a lost worker, bad input) cancels the chunks not yet started. Returns (the
    results, the failure or None)."""
    from distributed import as_completed

    results, failure = [], None
    for done, future in enumerate(as_completed(list(futures)), 1):
        spec = futures[future]
        try:
            result = future.result()
        except Exception as exc:  # a crash after its retries, or a lost worker (KilledWorker)
            reason = str(exc).strip().splitlines()[0] if str(exc).strip() else repr(exc)
            result = {"frames": spec, "error": reason, "bad_input": False}
        if "error" in result:
            failure = result
            client.cancel([f for f in futures if not f.done()])
            log(f"{stamp()} frames {spec} failed: {result['error']}")
            break
        results.append(result)
        totals = result["report"].get("totals") or {}
        counts = ", ".join(f"{totals[k]} {k}" for k in ("rendered", "skipped") if k in totals)
        log(
            f"{stamp()} {done}/{count} frames {spec}: {counts or 'done'} on "
            f"{result['host']} ({result['worker']}) in {result['seconds']:.1f} s"
        )
    return results, failure


def _merged_report(results, failure, frames, path, started, farm) -> dict:
    """The chunks' reports merged, in frame order, with the report already at ``path`` (a
    re-run's skipped frames), the ``farm`` fields (scheduler, chunk_size, retries) and the
    chunks; incomplete with ``failure``. Written to ``path`` (atomic) and returned."""
    results.sort(key=lambda r: parse_frames(r["frames"])[0])
    report = merge_reports(
        [r["report"] for r in results],
        requested=format_frames(parse_frames(frames)),
        previous=read_report(path),
        wall_seconds=time.perf_counter() - started,
    )
    report["farm"] = {
        "scheduler": farm["scheduler"],
        "chunk_size": farm["chunk_size"],
        "chunks": [{k: r[k] for k in ("frames", "host", "worker", "seconds")} for r in results],
        "retries": farm["retries"],
    }
    if failure:
        report["complete"] = False
        report["farm"]["failed"] = {"frames": failure["frames"], "error": failure["error"]}
    write_json_atomic(path, report)
    return report


# -- command line ----------------------------------------------------------------------------


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, not argparse's usage block
        print(f"farm: error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


def parse(argv):
    if "--" in argv:
        at = argv.index("--")
        argv, extra = argv[:at], argv[at + 1 :]
    else:
        extra = []
    p = _Parser(
        prog="python -m pipeline.farm",
        description=__doc__.splitlines()[0],
        epilog="Arguments after -- go to render_shot for every chunk (e.g. -- --samples 64).",
        allow_abbrev=False,  # `--ou` is no `--out`: each option by its whole name
    )
    p.add_argument("--scheduler", required=True, help="Dask scheduler address, tcp://host:8786")
    p.add_argument("shot", help="the shot (.blend), on shared storage")
    p.add_argument("--plate", required=True, help="plate file or sequence (plate.####.exr)")
    p.add_argument("--out", required=True, help="output folder, on shared storage")
    p.add_argument("--frames", required=True, help=FRAMES_HELP)
    p.add_argument("--chunk", type=int, default=10, help="frames per task (default 10)")
    how = p.add_mutually_exclusive_group()
    how.add_argument("--blender", help="Blender binary on the workers (same path on each)")
    how.add_argument("--bpy", action="store_true", help="the workers' Python with bpy (default)")
    p.add_argument("--extension", default=str(EXTENSION), help="extension folder on the workers")
    p.add_argument("--retries", type=int, default=2, help="re-runs of a crashed chunk")
    p.add_argument("--timeout", type=float, default=None, help="seconds per chunk")
    args = p.parse_args(argv)
    args.extra = extra
    return args


def main(argv=None):
    """The command line. Exit codes: 0 done; 2 bad input (ours, or render_shot's for a chunk),
    1 a chunk that kept crashing or a scheduler out of reach; either way one line on stderr."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = parse(argv)
    except SystemExit as exc:
        return EXIT_BAD_INPUT if exc.code else 0
    try:
        plan_chunks(args.frames, args.chunk)
        _validate_extra(args.extra)
        if args.retries < 0:
            raise ValueError("--retries must be 0 or more")
        if not os.path.isfile(os.path.join(args.extension, "render_shot.py")):
            raise ValueError(f"no render_shot.py in the extension folder {args.extension}")
        if not os.path.isfile(args.shot):  # the driver sees the shared storage too
            raise ValueError(f"shot not found: {args.shot}")
        prefix, cwd = batch_command(os.path.abspath(args.shot), args.blender, args.extension)
        run_farm(
            args.scheduler,
            args.shot,
            args.plate,
            args.out,
            args.frames,
            args.chunk,
            command_prefix=prefix,
            cwd=cwd,
            extra_args=args.extra,
            retries=args.retries,
            timeout=args.timeout,
            log=lambda line: print(line, flush=True),
        )
    except ValueError as exc:
        return _fail(exc, EXIT_BAD_INPUT)
    except FarmError as exc:
        return _fail(exc, EXIT_BAD_INPUT if exc.bad_input else 1)
    except OSError as exc:  # the scheduler out of reach, OUT not writable
        return _fail(exc, 1)
    return 0


def _fail(exc, code):
    print(f"farm: error: {(str(exc).strip() or repr(exc)).splitlines()[0]}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
