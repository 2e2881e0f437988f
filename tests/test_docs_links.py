"""The user documentation stands alone: every relative link in README.md and docs/**/*.md
reaches a file of this repository (and, with ``#anchor``, a heading of that file), no link
climbs out of the repository, and nothing points at a folder outside it.

Anchors follow GitHub's heading slugs: the heading's text as rendered (code spans, emphasis
and links reduced to their text), lower-cased, every character other than a letter, a digit,
``_``, ``-`` or a space dropped, each space turned into ``-``; a repeated slug gets ``-1``,
``-2``, ... Also checked: the README's two command lines are the ones ``.ci/run`` and users run.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

_FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})")
_ATX = re.compile(r"^ {0,3}(#{1,6})(?:[ \t]+(.*?))?(?:[ \t]+#+)?[ \t]*$")
_SETEXT = re.compile(r"^ {0,3}(=+|-+)[ \t]*$")
_CODE_SPAN = re.compile(r"(`+)(.+?)\1", re.S)
_INLINE_LINK = re.compile(
    r"!?\[((?:[^\[\]]|\[[^\]]*\])*)\]"  # [text] or ![alt], one level of nested brackets
    r"\(\s*(<[^>]*>|[^\s)]+)(?:\s+[\"'(][^)]*)?\s*\)"  # (target "optional title")
)
_REF_DEF = re.compile(r"^ {0,3}\[[^\]]+\]:\s*(<[^>]*>|\S+)", re.M)
_HTML_ID = re.compile(r"<a\s+(?:name|id)=[\"']([^\"']+)[\"']", re.I)
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")
_OUTSIDE = "../shared"
_MAIN_JOB = ("python3 -m venv .venv && .venv/bin/pip install -q -e . && .venv/bin/hilnav up "
             "--duration 600 --speed 10 --gnss-off 300:60 --out out/up")


@dataclass(frozen=True)
class Link:
    """A link of a Markdown file: where it is and what it points to."""

    source: Path
    line: int
    target: str


def doc_files(root: Path) -> list[Path]:
    """README.md and every Markdown file under docs/ (sorted)."""
    files = [root / "README.md"] if (root / "README.md").is_file() else []
    return files + sorted((root / "docs").rglob("*.md"))


def prose_lines(text: str) -> list[tuple[int, str]]:
    """``(line number, line)`` of the lines outside fenced code blocks, code spans blanked."""
    out: list[tuple[int, str]] = []
    fence: str | None = None
    for number, line in enumerate(text.splitlines(), start=1):
        m = _FENCE.match(line)
        if fence is None and m:
            fence = m.group(1)[0] * len(m.group(1))
            continue
        if fence is not None:
            if line.strip().startswith(fence) and set(line.strip()) <= {fence[0]}:
                fence = None
            continue
        out.append((number, _CODE_SPAN.sub(lambda c: " " * len(c.group(0)), line)))
    return out


def heading_text(raw: str) -> str:
    """A heading's text as GitHub renders it: code spans, links, images and emphasis reduced
    to their text, HTML tags removed."""
    text = _CODE_SPAN.sub(lambda c: c.group(2).strip(), raw)
    text = _INLINE_LINK.sub(lambda m: m.group(1), text)
    text = re.sub(r"<[^>]+>", "", text)
    text = re.sub(r"(\*{1,3})(\S(?:.*?\S)?)\1", r"\2", text)
    # an underscore inside a word (snake_case) is not emphasis
    return re.sub(r"(?<!\w)(_{1,3})(\S(?:.*?\S)?)\1(?!\w)", r"\2", text)


def slug(text: str) -> str:
    """GitHub's anchor of a heading whose rendered text is ``text`` (without the duplicate
    suffix)."""
    kept = re.sub(r"[^\w\- ]", "", text.strip().lower())
    return kept.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every anchor GitHub makes for ``path``: its headings' slugs (duplicates numbered) and
    explicit ``<a name=...>`` / ``<a id=...>`` targets."""
    text = path.read_text(encoding="utf-8")
    seen: dict[str, int] = {}
    out: set[str] = set()
    previous = ""
    fence: str | None = None
    for line in text.splitlines():
        m = _FENCE.match(line)
        if fence is None and m:
            fence, previous = m.group(1)[0] * len(m.group(1)), ""
            continue
        if fence is not None:
            if line.strip().startswith(fence) and set(line.strip()) <= {fence[0]}:
                fence = None
            continue
        title: str | None = None
        atx = _ATX.match(line)
        if atx:
            title = atx.group(2) or ""
        elif _SETEXT.match(line) and previous.strip() and not _ATX.match(previous):
            title = previous.strip()
        previous = line
        out.update(_HTML_ID.findall(line))
        if title is None:
            continue
        base = slug(heading_text(title))
        count = seen.get(base, 0)
        seen[base] = count + 1
        out.add(base if count == 0 else f"{base}-{count}")
    return out


def links(path: Path) -> list[Link]:
    """The links of a Markdown file outside code: inline links, images, reference
    definitions."""
    text = path.read_text(encoding="utf-8")
    found: list[Link] = []
    for number, line in prose_lines(text):
        for m in _INLINE_LINK.finditer(line):
            found.append(Link(path, number, m.group(2).strip("<>")))
        for m in _REF_DEF.finditer(line):
            found.append(Link(path, number, m.group(1).strip("<>")))
    return found


def link_problems(root: Path, files: Iterable[Path]) -> list[str]:
    """One line per broken link or outside reference in ``files`` (paths under ``root``)."""
    root = root.resolve()
    problems: list[str] = []
    cache: dict[Path, set[str]] = {}
    for path in files:
        rel = path.resolve().relative_to(root)
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if _OUTSIDE in line:
                problems.append(f"{rel}:{number}: mentions {_OUTSIDE} (outside the repository)")
        for link in links(path):
            where = f"{rel}:{link.line}: {link.target}"
            if _SCHEME.match(link.target) or link.target.startswith("//"):
                continue  # a web address
            file_part, _, anchor = link.target.partition("#")
            if file_part.startswith("/"):
                problems.append(f"{where}: absolute path; link relative to the file")
                continue
            target = (path.parent / file_part).resolve() if file_part else path.resolve()
            if not target.is_relative_to(root):
                problems.append(f"{where}: leaves the repository")
                continue
            if not target.exists():
                problems.append(f"{where}: no such file")
                continue
            if anchor:
                if target.suffix.lower() != ".md" or not target.is_file():
                    problems.append(f"{where}: an anchor into a file that is not Markdown")
                    continue
                if target not in cache:
                    cache[target] = anchors(target)
                if anchor not in cache[target]:
                    problems.append(f"{where}: no heading with anchor #{anchor}")
    return problems


# ------------------------------------------------------------------------------------ tests


def test_every_link_of_the_user_docs_resolves_inside_the_repository() -> None:
    # GIVEN the README and every page under docs/
    files = doc_files(ROOT)
    assert ROOT / "README.md" in files
    # WHEN every relative link is followed
    problems = link_problems(ROOT, files)
    # THEN each reaches a file (and heading) of this repository
    assert problems == [], "\n".join(problems)


def test_the_ci_entry_runs_exactly_the_readme_test_command() -> None:
    # GIVEN the command .ci/run executes (its last line)
    ci = [ln for ln in (ROOT / ".ci" / "run").read_text().splitlines()
          if ln.strip() and not ln.startswith("#")]
    readme = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    # THEN the README shows that very line, and the main job's line
    assert ci[-1] in readme
    assert _MAIN_JOB in readme


@pytest.mark.parametrize(("heading", "anchor"), [
    ("Bridging (GMDH and the learned methods)", "bridging-gmdh-and-the-learned-methods"),
    ("PX4 (SITL / HITL)", "px4-sitl--hitl"),
    ("Robustness (fuzz, soak, security)", "robustness-fuzz-soak-security"),
    ("Output of `replay` / `demo`", "output-of-replay--demo"),
    ("The **navigation** filter", "the-navigation-filter"),
    ("Lockstep with PX4 and ArduPilot", "lockstep-with-px4-and-ardupilot"),
    ("Dépendances_1.2", "dépendances_12"),
    ("wind_shear_exponent and _emphasis_", "wind_shear_exponent-and-emphasis"),
])
def test_anchors_follow_github_slugs(heading: str, anchor: str) -> None:
    assert slug(heading_text(heading)) == anchor


def _write(root: Path, name: str, text: str) -> Path:
    path = root / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def test_the_checker_accepts_good_links(tmp_path: Path) -> None:
    # GIVEN a small repository whose links all resolve
    _write(tmp_path, "docs/a.md", "# Title\n\n## Same\n\n## Same\n\nSetext\n------\n")
    _write(tmp_path, "docs/img/p.png", "")
    readme = _write(tmp_path, "README.md", (
        "[a](docs/a.md) [b](docs/a.md#title) [dup](docs/a.md#same-1) [s](docs/a.md#setext)\n"
        "![p](docs/img/p.png) [web](https://example.org/x#y) [self](#top)\n\n# Top\n"
        "```\n[in code](missing.md)\n```\n`[span](missing.md)`\n[ref]: docs/a.md\n"))
    # THEN nothing is reported
    assert link_problems(tmp_path, [readme, tmp_path / "docs/a.md"]) == []


def test_the_checker_reports_every_kind_of_broken_link(tmp_path: Path) -> None:
    # GIVEN links to a missing file, a missing heading, out of the repository and a mention
    # of a folder outside it
    _write(tmp_path, "docs/a.md", "# Title\n")
    page = _write(tmp_path, "docs/b.md", (
        "[gone](missing.md)\n[anchor](a.md#nope)\n[up](../../etc/passwd)\n"
        "[abs](/docs/a.md)\nsee ../shared/papers/README.md\n[ok](a.md#title)\n"))
    # WHEN checked
    problems = link_problems(tmp_path, [page])
    # THEN each is reported once, with its line
    assert len(problems) == 5, problems
    assert problems[0].startswith("docs/b.md:5: mentions ../shared")
    assert "missing.md: no such file" in problems[1]
    assert "#nope" in problems[2]
    assert "leaves the repository" in problems[3]
    assert "absolute path" in problems[4]
