"""Every file the documentation names exists: README.md and docs/*.md.

Checked: markdown links ``[text](path)`` (relative to the page; web addresses and in-page anchors
are not followed), backticked paths that start with a top-level folder of the repository
(``jobs/box_test.toml``, ``pdem/build/config.py``, ``pdem/io/_h5.ensure_space`` a name in a module:
relative to the repository root; command lines are split into words, placeholders such as
``<name>``, ``NAME`` or ``*`` are skipped, and so are outputs that git ignores, such as
``bench/cache/``), and every ``NAME.md`` a page mentions (relative to the page or the root; not
the outputs of runs, ``runs/...``).
"""
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
TOP = {p.name for p in ROOT.iterdir() if p.is_dir() and not p.name.startswith(".")} - {"runs", "build"}

LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
CODE = re.compile(r"`([^`\n]+)`")
MD_NAME = re.compile(r"(?<![\w/.-])([\w./-]+\.md)\b")
# <name>, *, {a,b}, ..., and upper-case words that stand for a name (runs/NAME/, RESULTS.h5; not SPEC.md)
PLACEHOLDER = re.compile(r"[<>*{}$\[\]|]|\.\.\.|(?:^|/)[A-Z][A-Z_]+(?:/|$|\.(?!md\b))")


def _links(text):
    for target in LINK.findall(text):
        if re.match(r"^[a-z]+:", target) or target.startswith("#"):
            continue
        yield target.split("#")[0]


def _code_paths(text):
    for code in CODE.findall(text):
        for word in code.split():
            word = word.strip(",;:()'\"").rstrip(".")
            word = re.sub(r"::.*$|:\d+$", "", word)
            if "/" in word and word.split("/")[0] in TOP and not PLACEHOLDER.search(word):
                yield word


def _md_names(text):
    text = LINK.sub("", text)
    for name in MD_NAME.findall(text):
        if "/" in name and name.split("/")[0] not in TOP | {".", ".."}:
            continue  # runs/.../checks.md: what a run writes
        if not name.startswith(("http", "www.")) and not PLACEHOLDER.search(name):
            yield name


def _exists(path):
    """A file or folder, a name in a module (pdem/io/_h5.ensure_space), or an ignored output."""
    module = re.sub(r"\.\w+$", ".py", path)
    if (ROOT / path).exists() or (module != path and (ROOT / module).exists()):
        return True
    return subprocess.run(["git", "-C", str(ROOT), "check-ignore", "-q", path]).returncode == 0


def dead_references(page):
    text = page.read_text()
    dead = [f"link {t}" for t in _links(text) if t and not (page.parent / t).exists()]
    dead += [f"path {p}" for p in _code_paths(text) if not _exists(p)]
    dead += [f"file {n}" for n in _md_names(text) if not ((page.parent / n).exists() or (ROOT / n).exists())]
    return sorted(set(dead))


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_file_the_page_names_exists(page):
    assert dead_references(page) == []


def test_the_checker_finds_dead_references(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("[ok](page.md) [gone](nowhere.md#x) [web](https://example.org) `jobs/box_test.toml`\n"
                    "`jobs/no_such_job.toml` `python -m pdem run jobs/gone.toml --out runs/NAME` `jobs/<name>.toml`\n"
                    "see SPEC_NOT_HERE.md 2.3 and README.md\n")
    assert dead_references(page) == ["file SPEC_NOT_HERE.md", "link nowhere.md", "path jobs/gone.toml",
                                     "path jobs/no_such_job.toml"]


def test_docs_index_names_every_page():
    index = (ROOT / "docs" / "index.md").read_text()
    missing = [p.name for p in PAGES if p.parent.name == "docs" and p.name != "index.md" and f"({p.name})" not in index]
    assert missing == []
