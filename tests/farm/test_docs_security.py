"""docs/pipeline.md never shows a Dask farm anyone on the network could use: every
`dask scheduler` and `dask worker` command binds to loopback or uses mutual TLS, with its
dashboard on loopback (issue 14, case 16; issue 40, row 19). The loopback set-up is started
as the docs write it, and every socket its processes listen on is checked."""

import re
import shlex
import socket
import subprocess
import sys
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[2] / "docs" / "pipeline.md"
LOOPBACK = ("127.0.0.1", "::1")


def joined_lines(text):
    """The text's lines with shell continuation lines (`\\` at the end) joined."""
    lines, out = text.splitlines(), []
    i = 0
    while i < len(lines):
        line = lines[i]
        while line.rstrip().endswith("\\") and i + 1 < len(lines):
            i += 1
            line = line.rstrip()[:-1] + " " + lines[i].strip()
        out.append(line)
        i += 1
    return out


def dask_commands(text, kind):
    """Each `dask <kind> ...` command (scheduler or worker) of the text, continuations joined."""
    return [
        line
        for line in joined_lines(text)
        if re.search(rf"\bdask[ -]{kind}\b", line) and not line.lstrip().startswith(("#", "|"))
    ]


def scheduler_commands(text):
    return dask_commands(text, "scheduler")


def shell_blocks(text):
    """The fenced code blocks of the text, each as its lines (indented fences too)."""
    blocks, block = [], None
    for line in text.splitlines():
        if line.strip().startswith("```"):
            if block is None:
                block = []
            else:
                blocks.append("\n".join(block))
                block = None
        elif block is not None:
            block.append(line)
    return blocks


def loopback_set_up(text):
    """The argv of each `dask scheduler`/`dask worker` command of the docs' one-machine
    set-up: the code block whose scheduler binds to 127.0.0.1."""
    for block in shell_blocks(text):
        argvs = [shlex.split(line, comments=True) for line in joined_lines(block)]
        argvs = [a for a in argvs if len(a) > 1 and Path(a[0]).name == "dask"]
        if any(a[1] == "scheduler" and "127.0.0.1" in a for a in argvs):
            return argvs
    return []


def test_every_scheduler_in_the_docs_is_loopback_or_tls():
    commands = scheduler_commands(DOC.read_text(encoding="utf-8"))
    assert commands, "the pipeline docs show how to start a scheduler"
    for command in commands:
        loopback = re.search(r"--host\s+(127\.0\.0\.1|localhost|::1)\b", command)
        tls = "--protocol tls" in command and "--tls-cert" in command and "--tls-ca-file" in command
        assert loopback or tls, command


def loopback_dashboard(command):
    """The command turns its dashboard off or puts it on loopback (by default Dask serves it
    on every interface: the scheduler's on 0.0.0.0:8787, each worker's on a random port)."""
    return "--no-dashboard" in command or re.search(
        r"--dashboard-address[ =](127\.0\.0\.1|localhost|\[::1\]):\d+", command
    )


def test_every_dashboard_in_the_docs_is_on_loopback():
    text = DOC.read_text(encoding="utf-8")
    commands = dask_commands(text, "scheduler") + dask_commands(text, "worker")
    assert dask_commands(text, "worker"), "the pipeline docs show how to start a worker"
    for command in commands:
        assert loopback_dashboard(command), command


def test_every_worker_in_the_docs_listens_on_loopback_or_uses_tls():
    """A worker without `--host` listens on every interface (0.0.0.0 and ::) whatever its
    scheduler's address, and anyone who reaches it runs code through it."""
    for command in dask_commands(DOC.read_text(encoding="utf-8"), "worker"):
        loopback = re.search(r"tcp://127\.0\.0\.1:\d+", command) and re.search(
            r"(--host[ =]127\.0\.0\.1|--listen-address[ =]tcp://127\.0\.0\.1:)", command
        )
        tls = re.search(r"\btls://", command) and all(
            option in command for option in ("--tls-ca-file", "--tls-cert", "--tls-key")
        )
        assert loopback or tls, command


def test_the_docs_say_what_an_open_scheduler_means():
    text = DOC.read_text(encoding="utf-8").lower()
    assert "runs" in text and "code" in text and "tls" in text


# -- the loopback set-up, started as documented ----------------------------------------------


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def on_free_ports(argvs):
    """The commands with each fixed port they name (`--port P`, `host:P`, scheduler default
    8786) moved to a free one, the same for every command, and `dask` run as this Python's."""
    ports = {}

    def moved(match):
        port = match.group(2)
        if port != "0":
            ports.setdefault(port, str(free_port()))
        return match.group(1) + ports.get(port, port)

    out = []
    for argv in argvs:
        if argv[1] == "scheduler" and not any(a.startswith("--port") for a in argv):
            argv = [*argv, "--port", "8786"]
        joined = "\0".join(argv[1:])
        joined = re.sub(r"((?:^|\0)--port[\0=])(\d+)", moved, joined)
        joined = re.sub(r"(:)(\d+)(?=\0|$)", moved, joined)
        out.append([sys.executable, "-m", "dask", *joined.split("\0")])
    return out, ports.get("8786")


def listening(psutil, pids):
    """(pid, address) of every listening socket of the processes and their children."""
    found = []
    for pid in pids:
        try:
            parent = psutil.Process(pid)
            tree = [parent, *parent.children(recursive=True)]
        except psutil.NoSuchProcess:
            continue
        for process in tree:
            try:
                connections = process.net_connections(kind="inet")
            except psutil.NoSuchProcess:
                continue
            found += [(process.pid, c.laddr) for c in connections if c.status == psutil.CONN_LISTEN]
    return found


def stop(psutil, processes):
    tree = []
    for p in processes:
        try:
            tree += [psutil.Process(p.pid), *psutil.Process(p.pid).children(recursive=True)]
        except psutil.NoSuchProcess:
            pass
    for p in reversed(processes):  # workers first, then the scheduler
        p.terminate()
    _, alive = psutil.wait_procs(tree, timeout=10)
    for p in alive:
        p.kill()
    for p in processes:
        p.wait(10)


def test_the_documented_loopback_farm_listens_only_on_loopback(tmp_path):
    """Starts the docs' one-machine scheduler and worker (free ports instead of 8786/8787),
    waits for the worker to join, and lists the socket every one of their processes —
    scheduler, nanny, worker — listens on: each is 127.0.0.1 or ::1."""
    distributed = pytest.importorskip("distributed", reason="pip install -r requirements/farm.txt")
    psutil = pytest.importorskip("psutil")
    argvs = loopback_set_up(DOC.read_text(encoding="utf-8"))
    kinds = [a[1] for a in argvs]
    assert kinds.count("scheduler") == 1, f"the docs' loopback set-up starts one scheduler: {argvs}"
    assert "worker" in kinds, f"the docs' loopback set-up starts a worker on that machine: {argvs}"
    commands, port = on_free_ports(sorted(argvs, key=lambda a: a[1] != "scheduler"))
    workers = sum(
        int(a[a.index("--nworkers") + 1]) if "--nworkers" in a else 1
        for a in argvs
        if a[1] == "worker"
    )
    processes, logs = [], []
    try:
        for i, command in enumerate(commands):
            logs.append(tmp_path / f"{command[3]}{i}.log")
            with open(logs[-1], "w") as log:
                processes.append(
                    subprocess.Popen(
                        command, stdin=subprocess.DEVNULL, stdout=log, stderr=log, cwd=tmp_path
                    )
                )
        try:
            with distributed.Client(f"tcp://127.0.0.1:{port}", timeout="20s") as client:
                client.wait_for_workers(workers, timeout=20)
        except (OSError, TimeoutError) as exc:
            tails = {log.name: log.read_text()[-600:] for log in logs}
            pytest.fail(f"the documented farm did not come up: {exc!r}; logs: {tails}")
        sockets = listening(psutil, [p.pid for p in processes])
    finally:
        stop(psutil, processes)
    # the scheduler and its dashboard, and each worker's nanny, worker and dashboard
    assert len(sockets) >= 2 + 2 * workers, sockets
    exposed = [(pid, f"{a.ip}:{a.port}") for pid, a in sockets if a.ip not in LOOPBACK]
    assert not exposed, (
        f"listening beyond loopback: {exposed}; commands: {[shlex.join(c[3:]) for c in commands]}"
    )
