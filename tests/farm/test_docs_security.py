"""docs/pipeline.md never shows a Dask scheduler anyone on the network could use: every
`dask scheduler` command binds to loopback or uses TLS (issue 14, case 16)."""

import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[2] / "docs" / "pipeline.md"


def scheduler_commands(text):
    """Each `dask scheduler ...` command with its continuation lines joined."""
    lines = text.splitlines()
    out = []
    for i, line in enumerate(lines):
        if re.search(r"\bdask[ -]scheduler\b", line) and not line.lstrip().startswith(("#", "|")):
            command = line
            while command.rstrip().endswith("\\") and i + 1 < len(lines):
                i += 1
                command = command.rstrip()[:-1] + " " + lines[i].strip()
            out.append(command)
    return out


def test_every_scheduler_in_the_docs_is_loopback_or_tls():
    commands = scheduler_commands(DOC.read_text(encoding="utf-8"))
    assert commands, "the pipeline docs show how to start a scheduler"
    for command in commands:
        loopback = re.search(r"--host\s+(127\.0\.0\.1|localhost|::1)\b", command)
        tls = "--protocol tls" in command and "--tls-cert" in command and "--tls-ca-file" in command
        assert loopback or tls, command


def test_the_docs_say_what_an_open_scheduler_means():
    text = DOC.read_text(encoding="utf-8").lower()
    assert "runs" in text and "code" in text and "tls" in text
