"""Documentation consistency: every section cited in the project ("THEORY §3.4", "§7.1–7.2",
"§6–8") is a heading of the theory manual docs/theory.md, and no file of the repository points
at a path outside it. Pure Python, no dolfinx."""

import os
import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MANUAL = ROOT / "docs" / "theory.md"
SECTION = "\u00a7"  # the section sign, spelled out so that this file cites nothing itself

#: where citations are searched
CITING = ("fxcontact", "demos", "benchmarks", "tests", "docs", "meshes", "scripts", "README.md")
TEXT_SUFFIXES = {".py", ".md", ".sh", ".toml", ".txt", ".cfg", ".ini", ".yml", ".yaml", ""}
SKIP_DIRS = {".git", ".venv", "venv", "__pycache__", "results", "build", "dist", ".pytest_cache"}

_NUM = r"(\d+(?:\.\d+)*)"
CITATION = re.compile(SECTION + r"\s*" + _NUM + r"(?:\s*[–-]\s*" + SECTION + r"?\s*" + _NUM + ")?")
HEADING = re.compile(r"^#{1,6}\s+" + _NUM + r"\.?\s")

#: strings that point outside the repository (assembled so that this file does not contain them)
OUTSIDE = ["/" + "work/", "../" + "shared", "/" + "shared/", "THEORY" + ".md", "PLATFORM" + ".md",
           "/" + "home/", "/" + "root/"]


def manual_sections():
    found = set()
    for line in MANUAL.read_text(encoding="utf-8").splitlines():
        m = HEADING.match(line)
        if m:
            found.add(m.group(1))
    return found


def repository_files():
    """Tracked files (git), else a walk of the checkout without virtualenvs, caches, results."""
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True,
                             timeout=30).stdout.decode()
        files = [ROOT / f for f in out.split("\0") if f]
        if files:
            return [f for f in files if f.is_file()]
    except (OSError, subprocess.SubprocessError):
        pass
    files = []
    for dirpath, dirnames, filenames in os.walk(ROOT):
        dirnames[:] = [d for d in dirnames if d not in SKIP_DIRS and not d.endswith(".egg-info")]
        files += [Path(dirpath) / f for f in filenames]
    return files


def text_files(paths=None):
    for f in repository_files():
        rel = f.relative_to(ROOT)
        if paths is not None and rel.parts[0] not in paths:
            continue
        if f.suffix not in TEXT_SUFFIXES:
            continue
        try:
            yield rel, f.read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue


def test_manual_has_the_sections_other_work_relies_on():
    sections = manual_sections()
    # friction (§9) and forming theory (§14: drawing, rolling, ring rolling, friction checks)
    for s in ("0.2", "1.1", "2.5", "3.4", "3.6", "5", "7.5", "8.3", "9", "14", "14.1", "14.2",
              "14.3", "14.4", "14.5"):
        assert s in sections, f"docs/theory.md has no heading for section {s}"
    text = MANUAL.read_text(encoding="utf-8")
    for topic in ("Avitzur", "Ring compression", "Upsetting a cylinder", "Power balance",
                  "Coulomb", "Tresca", "Norton"):
        assert topic in text, f"docs/theory.md does not mention {topic!r}"


def test_every_cited_section_exists():
    sections = manual_sections()
    missing = []
    n_citations = 0
    for rel, text in text_files(CITING):
        for lineno, line in enumerate(text.splitlines(), 1):
            for m in CITATION.finditer(line):
                n_citations += 1
                for num in filter(None, m.groups()):
                    if num not in sections:
                        missing.append(f"{rel}:{lineno}: {SECTION}{num}  ({line.strip()[:80]})")
    assert n_citations > 50  # the scan did find the code's citations
    assert not missing, "sections cited but absent from docs/theory.md:\n" + "\n".join(missing)


def test_no_path_outside_the_repository():
    bad = []
    for rel, text in text_files():
        for lineno, line in enumerate(text.splitlines(), 1):
            for s in OUTSIDE:
                if s in line:
                    bad.append(f"{rel}:{lineno}: {s!r} in {line.strip()[:80]}")
    assert not bad, "paths outside the repository:\n" + "\n".join(bad)


def test_referenced_documents_exist():
    """Every ``docs/<name>.md`` named in the repository is there."""
    missing = set()
    for rel, text in text_files():
        for name in re.findall(r"docs/([\w-]+\.md)", text):
            if not (ROOT / "docs" / name).is_file():
                missing.add(f"{rel}: docs/{name}")
    assert not missing, sorted(missing)


def test_citation_pattern():
    """The citation scanner reads single sections and both ends of ranges."""
    s = SECTION
    found = [[g for g in m.groups() if g] for m in CITATION.finditer(
        f"THEORY {s}3.4; {s}2–{s}3; {s}6–8; ({s}7.1–7.2), {s}11.2.")]
    assert found == [["3.4"], ["2", "3"], ["6", "8"], ["7.1", "7.2"], ["11.2"]]
