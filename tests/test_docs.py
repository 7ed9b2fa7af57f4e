"""Every citation resolves inside the repository, and the README stays a first page.

* A path-like citation of a repository file in a comment, a docstring or a docs page
  (`engine/...py`, `docs/....md`, `mcrt_addon/...`, `tests/...`, `scripts/...`, `sample_blends/...`,
  dotted modules such as `engine.film.passes`) names a file or directory of the git tree.
* Comments and docstrings cite no file outside it: no `shared/...` paths, no bare note names
  (`hard-cases.md`), no "the issue" or "issue 9", no hard-case label (H7, S4) without
  docs/hard-cases.md, and every label cited with it is in the catalogue.
* Every link of a docs page (and of the README) resolves, anchors included.
* README.md is at most 160 lines and starts with the two commands; docs/architecture.md names
  every package of engine/.

The files scanned are those of `git ls-files` that exist on disk, so the test follows moves and
renames of modules: it reads the tree as it is.  Research notes copied into docs/ carry the marker
REFERENCE_NOTE: their paths name other repositories, so only their links are checked.
"""
from __future__ import annotations

import ast
import io
import os
import re
import subprocess
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SELF = "tests/test_docs.py"
REFERENCE_NOTE = "<!-- reference-note:"
PREFIXES = ("engine", "mcrt_addon", "tests", "scripts", "sample_blends", "docs")
FILE_EXTENSIONS = {"py", "md", "json", "blend", "toml", "txt", "png", "ini", "npz", "exr", "sh", "cfg"}
PATH_RE = re.compile(r"(?<![\w./\-])((?:" + "|".join(PREFIXES) + r")/[\w./\-]*[\w/])")
DOTTED_RE = re.compile(r"(?<![\w./\-])((?:engine|mcrt_addon)(?:\.[A-Za-z_]\w*)+)")
PLACEHOLDER_RE = re.compile(r"\b[A-Z]{3,}\b")                      # sample_blends/NAME.blend
NOTE_NAMES = ("hard-cases", "light-sampling", "cluster-and-viewport", "blender-render-engines",
              "materials-and-caustics")
BARE_NOTE_RE = re.compile(r"(?<![\w/.\-])(?:(?:" + "|".join(NOTE_NAMES) + r")\.md|hard-cases(?![.\w-]))")
OUTSIDE_RE = re.compile(r"shared/reference|/work/|\bthe issue\b|\bissue \d+|\bissues? #\d+", re.IGNORECASE)
LABEL_RE = re.compile(r"\b([HSTC]\d{1,2})\b")
HARD_CASE_WORDS_RE = re.compile(r"hard[ -]cases?\b", re.IGNORECASE)
README_SECTION_RE = re.compile(r"README(?:[:,]\s*|\s+(?=[*\"]))[*\"]?([A-Z][A-Za-z' ]+)")
LINK_RE = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
COMMENT_FILES = ("Makefile", "requirements.txt", ".ci/run", "blender_manifest.toml", "pytest.ini")


# -- the tree ---------------------------------------------------------------------------------------

def git_files(root: Path) -> list[str]:
    out = subprocess.run(["git", "ls-files", "-z"], cwd=root, capture_output=True, check=True).stdout
    return sorted(p for p in out.decode().split("\0") if p and (root / p).is_file())


class Tree:
    """The files of a tree (relative POSIX paths) and the directories that hold them."""

    def __init__(self, root: Path, files):
        self.root = root
        self.files = set(files)
        self.dirs = {str(Path(f).parent.as_posix()) for f in self.files}
        for d in list(self.dirs):
            parts = d.split("/")
            self.dirs.update("/".join(parts[:i]) for i in range(1, len(parts)))

    def has(self, path: str) -> bool:
        path = path.rstrip("/")
        return path in self.files or path in self.dirs

    def read(self, path: str) -> str:
        return (self.root / path).read_text(encoding="utf-8", errors="replace")


# -- where citations are: comments, docstrings and docs -----------------------------------------------

def python_texts(source: str):
    """(line, text) of every comment block (consecutive comment lines joined) and docstring."""
    texts = []
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(source).readline))
    except (tokenize.TokenError, SyntaxError):
        tokens = []
    block, start, last = [], 0, -2
    for tok in tokens:
        if tok.type != tokenize.COMMENT:
            continue
        line = tok.start[0]
        if line != last + 1 and block:
            texts.append((start, "\n".join(block)))
            block = []
        if not block:
            start = line
        block.append(tok.string.lstrip("#"))
        last = line
    if block:
        texts.append((start, "\n".join(block)))
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return texts
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                texts.append((body[0].lineno, body[0].value.value))
    return texts


def hash_comment_texts(source: str):
    return [(i, line.split("#", 1)[1]) for i, line in enumerate(source.splitlines(), 1) if "#" in line]


def cited_texts(tree: Tree):
    """(path, line, text, kind) with kind 'code' (comments, docstrings) or 'doc' (a docs page)."""
    for path in sorted(tree.files):
        if path == SELF:
            continue                     # its docstring and controls quote broken citations
        if path.endswith(".py"):
            for line, text in python_texts(tree.read(path)):
                yield path, line, text, "code"
        elif path.endswith(".md") and (path.startswith("docs/") or "/" not in path):
            text = tree.read(path)
            if REFERENCE_NOTE not in text:
                yield path, 1, text, "doc"
        elif path in COMMENT_FILES or path.startswith("scripts/") and path.endswith(".sh"):
            for line, text in hash_comment_texts(tree.read(path)):
                yield path, line, text, "code"


# -- the checks --------------------------------------------------------------------------------------

def defines(tree: Tree, module_file: str, name: str) -> bool:
    """`name` is defined or imported at the top of `module_file` (a def, class, assignment, import)."""
    pattern = (rf"^(?:\s*(?:async\s+)?(?:def|class)\s+{name}\b|{name}\s*(?::[^=\n]*)?=|"
               rf"(?:from\s+\S+\s+)?import\s.*\b{name}\b)")
    return module_file in tree.files and re.search(pattern, tree.read(module_file), re.MULTILINE) is not None


def module_resolves(tree: Tree, parts: list) -> bool:
    """A package path down to a module or package; a name after it must be defined there."""
    path = parts[0]
    if path not in tree.dirs:
        return False
    for i, part in enumerate(parts[1:], 1):
        if f"{path}/{part}" in tree.dirs:
            path = f"{path}/{part}"
        elif tree.has(f"{path}/{part}.py"):
            rest = parts[i + 1:]
            return not rest or defines(tree, f"{path}/{part}.py", rest[0])
        else:
            return defines(tree, f"{path}/__init__.py", part)
    return True


def path_resolves(tree: Tree, cited: str) -> bool:
    if PLACEHOLDER_RE.search(cited) or tree.has(cited):
        return True
    head, _, last = cited.rstrip("/").rpartition("/")
    stem, dot, rest = last.partition(".")
    if dot and rest.split(".")[0] not in FILE_EXTENSIONS:    # engine/rendering/session.RenderSession
        return module_resolves(tree, head.split("/") + [stem] + rest.split("."))
    return not dot and tree.has(cited + ".py")                 # engine/lights/seen


def dotted_resolves(tree: Tree, cited: str) -> bool:
    """engine.film.passes, engine.pools.dask_cluster.RENDER_WORKER_CONFIG, mcrt_addon.register."""
    return module_resolves(tree, cited.split("."))


def catalogue_labels(tree: Tree) -> set:
    if "docs/hard-cases.md" not in tree.files:
        return set()
    return set(re.findall(r"^\| ([HSTC]\d{1,2}) \|", tree.read("docs/hard-cases.md"), re.MULTILINE))


def label_range(first: str, last: str):
    return [f"{first[0]}{i}" for i in range(int(first[1:]), int(last[1:]) + 1)]


def readme_sections(tree: Tree) -> list:
    if "README.md" not in tree.files:
        return []
    return [h.strip("# ").lower() for h in tree.read("README.md").splitlines() if h.startswith("#")]


def citation_problems(tree: Tree) -> list[str]:
    problems = []
    labels = catalogue_labels(tree)
    sections = readme_sections(tree)
    for path, line, text, kind in cited_texts(tree):
        def where(m, path=path, line=line, text=text):
            return f"{path}:{line + text.count(chr(10), 0, m.start())}"
        for m in PATH_RE.finditer(text):
            if not path_resolves(tree, m.group(1)):
                problems.append(f"{where(m)}: cites {m.group(1)}, which is not in the repository")
        for m in DOTTED_RE.finditer(text):
            if not dotted_resolves(tree, m.group(1)):
                problems.append(f"{where(m)}: cites module {m.group(1)}, which is not in the repository")
        if kind != "code":
            continue
        for m in BARE_NOTE_RE.finditer(text):
            name = m.group(0) if m.group(0).endswith(".md") else m.group(0) + ".md"
            problems.append(f"{where(m)}: cites {m.group(0)} without its path (docs/{name})")
        for m in OUTSIDE_RE.finditer(text):
            problems.append(f"{where(m)}: cites {m.group(0)!r}, which is not in the repository")
        for m in README_SECTION_RE.finditer(text):
            name = m.group(1).strip().lower()
            if not any(s.startswith(name) or name.startswith(s) for s in sections if s):
                problems.append(f"{where(m)}: cites README section {m.group(1).strip()!r}, which it does not have")
        if HARD_CASE_WORDS_RE.search(text) or (LABEL_RE.search(text) and "docs/hard-cases.md" in text):
            cited = list(LABEL_RE.finditer(text))
            if cited and "docs/hard-cases.md" not in text:
                problems.append(f"{where(cited[0])}: hard-case label {cited[0].group(1)} without docs/hard-cases.md")
            if "docs/hard-cases.md" in text:
                names = [m.group(1) for m in cited]
                for a, b in re.findall(r"\b([HSTC]\d{1,2})\s*[-–]\s*([HSTC]?\d{1,2})\b", text):
                    names += label_range(a, b if b[0].isalpha() else a[0] + b)
                for label in names:
                    if label not in labels:
                        problems.append(f"{path}:{line}: hard case {label} is not in docs/hard-cases.md")
    return problems


def github_anchor(heading: str) -> str:
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(text: str) -> set:
    out, seen = set(), {}
    in_code = False
    for line in text.splitlines():
        if line.startswith("```"):
            in_code = not in_code
        if in_code or not line.startswith("#"):
            continue
        a = github_anchor(line.lstrip("#"))
        n = seen.get(a, 0)
        out.add(a if n == 0 else f"{a}-{n}")
        seen[a] = n + 1
    return out


def link_problems(tree: Tree) -> list[str]:
    problems = []
    pages = [p for p in sorted(tree.files) if p.endswith(".md") and (p.startswith("docs/") or "/" not in p)]
    for page in pages:
        text = tree.read(page)
        prose = re.sub(r"```.*?```", "", text, flags=re.DOTALL)
        for m in LINK_RE.finditer(prose):
            target = m.group(1)
            if re.match(r"[a-z]+:", target):
                continue                                   # https:, mailto:
            file_part, _, anchor = target.partition("#")
            resolved = os.path.normpath(os.path.join(os.path.dirname(page), file_part)).replace(os.sep, "/") \
                if file_part else page
            if not tree.has(resolved):
                problems.append(f"{page}: link {target} does not resolve ({resolved} is not in the repository)")
            elif anchor and resolved.endswith(".md") and anchor not in anchors(tree.read(resolved)):
                problems.append(f"{page}: link {target}: {resolved} has no heading #{anchor}")
    return problems


def readme_problems(tree: Tree, max_lines: int = 160) -> list[str]:
    lines = tree.read("README.md").splitlines()
    problems = []
    if len(lines) > max_lines:
        problems.append(f"README.md has {len(lines)} lines (at most {max_lines})")
    body = [ln for ln in lines if ln.strip() and not ln.startswith("# ")]
    if body[:3] != ["```", body[1], body[2]] or not body[1].startswith("make render") \
            or not body[2].startswith("make test"):
        problems.append("README.md does not start with the two commands (make render, make test)")
    return problems


def architecture_problems(tree: Tree) -> list[str]:
    if "docs/architecture.md" not in tree.files:
        return ["docs/architecture.md is missing"]
    text = tree.read("docs/architecture.md")
    packages = sorted({f.split("/")[1] for f in tree.files
                       if f.startswith("engine/") and f.count("/") == 2 and f.endswith("/__init__.py")})
    modules = sorted(f for f in tree.files if f.startswith("engine/") and f.count("/") == 1
                     and f.endswith(".py") and not f.endswith(("__init__.py", "__main__.py")))
    return ([f"docs/architecture.md does not name the package engine/{p}/" for p in packages
             if f"engine/{p}/" not in text]
            + [f"docs/architecture.md does not name {m}" for m in modules if m not in text])


# -- the tests ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def tree():
    try:
        files = git_files(ROOT)
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: the files to scan are the git tree")
    return Tree(ROOT, files)


def test_citations_resolve(tree):
    problems = citation_problems(tree)
    assert not problems, f"{len(problems)} citations do not resolve:\n" + "\n".join(problems)


def test_docs_links_resolve(tree):
    problems = link_problems(tree)
    assert not problems, "\n".join(problems)


def test_readme_is_a_first_page(tree):
    assert not readme_problems(tree)


def test_architecture_names_every_package(tree):
    assert not architecture_problems(tree)


def make_tree(tmp_path, files: dict) -> Tree:
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    return Tree(tmp_path, files)


GOOD_CATALOGUE = "| H7 | a ray in the plane |\n| S4 | TIR at the critical angle |\n"


def test_control_good_citations_pass(tmp_path):
    t = make_tree(tmp_path, {
        "README.md": "# X\n\n```\nmake render   # ...\nmake test     # ...\n```\n\n## Stopping rules\n",
        "docs/hard-cases.md": GOOD_CATALOGUE,
        "docs/guide.md": "# Guide\n\n## Two words\n\nSee [the cases](hard-cases.md), [here](#two-words), "
                         "`engine/film/passes.py` and [the site](https://example.org).\n",
        "engine/film/passes.py": '"""Passes (docs/hard-cases.md H7; docs/guide.md; README: Stopping rules)."""\n'
                                 "# the module engine.film.passes and engine/film/passes.NOISY; tests/ and\n"
                                 "# sample_blends/NAME.blend\n",
    })
    assert citation_problems(t) == []
    assert link_problems(t) == []
    assert readme_problems(t) == []


def test_control_fake_citations_are_reported(tmp_path):
    """Negative control: each kind of broken citation in a temporary tree is reported."""
    t = make_tree(tmp_path, {
        "README.md": "# X\n\nSome words first.\n\n```\nmake render\nmake test\n```\n" + "line\n" * 160,
        "docs/hard-cases.md": GOOD_CATALOGUE,
        "docs/guide.md": "# Guide\n\nSee [gone](missing.md), [anchor](hard-cases.md#nowhere) and "
                         "`engine/gone.py`.\n",
        "engine/film/passes.py": '"""Reads engine/film/nothing.py (docs/hard-cases.md H99)."""\n'
                                 "# hard case S4, as ../shared/reference/hard-cases.md says (hard-cases §3)\n"
                                 "x = 1\n"
                                 "# the issue's bound (issue 9); light-sampling.md; README: Layout; README \"Tools\"\n"
                                 "# engine.service.render_in_workers\n",
    })
    problems = "\n".join(citation_problems(t))
    for expected in ("engine/film/nothing.py", "hard case H99", "label S4 without", "shared/reference",
                     "'the issue'", "'issue 9'", "light-sampling.md without its path", "README section 'Layout'",
                     "README section 'Tools'", "hard-cases without its path",
                     "module engine.service.render_in_workers", "docs/guide.md:3: cites engine/gone.py"):
        assert expected in problems, expected
    links = "\n".join(link_problems(t))
    assert "missing.md does not resolve" in links and "#nowhere" in links
    readme = readme_problems(t)
    assert len(readme) == 2


def test_control_architecture_missing_package(tmp_path):
    t = make_tree(tmp_path, {"docs/architecture.md": "`engine/core/`", "engine/core/__init__.py": "",
                             "engine/newpkg/__init__.py": "", "engine/api.py": ""})
    assert architecture_problems(t) == ["docs/architecture.md does not name the package engine/newpkg/",
                                        "docs/architecture.md does not name engine/api.py"]
