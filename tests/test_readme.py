"""The README's commands name options that exist: every `--option` the README gives a tool is
one of that tool's parser's options, and every `--option a|b|c` lists exactly that option's
choices. A paragraph, list item or line of a code block is about the first tool it names; one that
names none is checked against every tool."""

import argparse
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
README = ROOT / "README.md"

# Blender's own flags the README uses around the tools (blender -b --python ... --).
BLENDER_FLAGS = {"--command", "--python", "--python-expr", "--python-exit-code", "--background"}
OPTION = re.compile(r"(?<![\w-])(--[a-z][a-z0-9-]*)(?:[ =]([A-Za-z0-9_.]+(?:\|[A-Za-z0-9_.]+)+))?")


def _options(parser: argparse.ArgumentParser) -> dict[str, tuple | None]:
    """Every option string of a parser (and its sub-commands) -> its choices, or None."""
    found: dict[str, tuple | None] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                for name, choices in _options(sub).items():
                    found[name] = found.get(name) or choices
            continue
        for name in action.option_strings:
            found[name] = tuple(action.choices) if action.choices else None
    return found


def _build_extension_options() -> dict[str, tuple | None]:
    text = (ROOT / "tools" / "build-extension").read_text()
    return {name: None for name in re.findall(r"^\s+(--[a-z-]+)\)", text, re.M)}


def _tools() -> dict[str, dict[str, tuple | None]]:
    import render_shot
    from study import cli as study_cli
    from virtual_reflections import cli as engine_cli

    sample = (ROOT / "sample_scenes" / "render_sample.py").read_text()
    return {
        "render_shot": _options(render_shot.parser()),
        "engine": _options(engine_cli.build_parser()),
        "study": _options(study_cli.build_parser()),
        "build-extension": _build_extension_options(),
        "render-sample": dict.fromkeys(re.findall(r'add_argument\("(--[a-z-]+)"', sample)),
    }


# Which tool a paragraph or line is about: the first of these it names.
TOOL_NAMES = (
    ("render_shot", re.compile(r"render_shot|blender -c virtual_reflections|blender -b ")),
    ("engine", re.compile(r"-m virtual_reflections|virtual_reflections (envmap|segment)")),
    ("study", re.compile(r"-m study")),
    ("build-extension", re.compile(r"build-extension")),
    ("render-sample", re.compile(r"render-sample|render_sample")),
)


def _chunks(text: str):
    """Per paragraph or list item outside code blocks, per line inside them."""
    in_code, paragraph = False, []
    for line in text.splitlines() + [""]:
        if line.startswith("```"):
            in_code = not in_code
            continue
        if in_code:
            yield line
        elif line.strip():
            if re.match(r"\s*(- |\d+\. )", line) and paragraph:  # a list item starts a chunk
                yield " ".join(paragraph)
                paragraph = []
            paragraph.append(line)
        elif paragraph:
            yield " ".join(paragraph)
            paragraph = []


def _tool_of(chunk: str) -> str | None:
    hits = [(m.start(), name) for name, rx in TOOL_NAMES for m in [rx.search(chunk)] if m]
    return min(hits)[1] if hits else None


def _mentions():
    text = README.read_text(encoding="utf-8")
    previous = command = ""
    for chunk in _chunks(text):
        # a code line continuing the one before (which ended in a backslash) is the same command
        if not previous.rstrip().endswith("\\"):
            command = chunk
        previous = chunk
        tool = _tool_of(command)
        for m in OPTION.finditer(chunk):
            yield tool, m.group(1), m.group(2), chunk


@pytest.fixture(scope="module")
def tools():
    return _tools()


def test_the_readme_names_options(tools):
    mentions = list(_mentions())
    assert len(mentions) > 30, "the README's options were not found: is the pattern wrong?"
    assert {"render_shot", "engine"} <= {tool for tool, *_ in mentions}


def test_every_option_the_readme_names_exists(tools):
    every = {name for options in tools.values() for name in options}
    missing = []
    for tool, name, _, chunk in _mentions():
        if name in BLENDER_FLAGS:
            continue
        known = tools[tool] if tool else every
        if name not in known:
            missing.append(f"{name} ({tool or 'any tool'}): {chunk[:90]}")
    assert not missing, "options the README names that the parsers lack:\n" + "\n".join(missing)


def test_every_choice_list_the_readme_gives_is_the_parsers(tools):
    wrong = []
    for tool, name, values, _ in _mentions():
        if not values or name in BLENDER_FLAGS:
            continue
        listed = [v.lower() for v in values.split("|")]
        candidates = [tools[tool].get(name)] if tool else [o.get(name) for o in tools.values()]
        choices = [
            [str(c).lower() for c in found if str(c).lower() != "frustum"]
            for found in candidates
            if found
        ]
        if choices and sorted(listed) not in [sorted(c) for c in choices]:
            wrong.append(f"{name} {values} ({tool}): parser has {choices}")
    assert not wrong, "README choice lists unlike the parsers':\n" + "\n".join(wrong)


def test_a_wrong_choice_list_is_caught(tools, monkeypatch, tmp_path):
    """The check fails on the README's old line (`render_shot --method camera|paper`)."""
    bad = tmp_path / "README.md"
    bad.write_text("Options of `render_shot`: `--method camera|paper`, `--objects`.\n")
    monkeypatch.setattr(__import__(__name__), "README", bad)
    with pytest.raises(AssertionError, match="--method camera\\|paper"):
        test_every_choice_list_the_readme_gives_is_the_parsers(tools)
    bad.write_text("`render_shot --no-such-option` and `--objects`\n")
    with pytest.raises(AssertionError, match="--no-such-option"):
        test_every_option_the_readme_names_exists(tools)
