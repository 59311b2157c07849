"""The documentation site: ``sphinx-build -W`` builds it with the gallery run, and it shows the API.

The site is built once per session, as CI builds it (``python -m sphinx -W -b html -c docs .
OUT``, from the repository's root: see ``docs/conf.py``), with every warning an error and the
gallery's scripts in ``examples/`` run. The tests then read the built pages, and open the API
reference and a gallery page in headless Chromium (Debian's ``/usr/bin/chromium``, which
``.ci/run`` installs).
"""

from __future__ import annotations

import ast
import html
import importlib
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

import ipcverify

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("plot_*.py"))
CHROMIUM = Path("/usr/bin/chromium")
FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]  # fmt: skip
#: The public API's cap (issue 39); ``tests/ipcverify/test_layout.py`` counts the same names.
MAX_PUBLIC_NAMES = 60


def public_names() -> dict[str, str]:
    """Every public name (``__all__`` of ipcverify's packages and ``ipcverify.errors``) -> its module."""
    modules = ["ipcverify", "ipcverify.errors"]
    for info in pkgutil.walk_packages(ipcverify.__path__, "ipcverify."):
        if info.ispkg and not any(part.startswith("_") for part in info.name.split(".")):
            modules.append(info.name)
    names: dict[str, str] = {}
    for name in modules:
        for n in importlib.import_module(name).__all__:
            if not n.startswith("__"):
                names.setdefault(n, name)
    return names


@pytest.fixture(scope="session")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The built site's HTML folder (the build's output is in the assertion if it fails)."""
    out = tmp_path_factory.mktemp("site") / "html"
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", "-c", "docs", "."]
    cmd.append(str(out))
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=1200)
    assert res.returncode == 0, f"sphinx-build -W failed:\n{res.stdout[-5000:]}\n{res.stderr[-5000:]}"
    return out


def _text(fragment: str, sep: str = " ") -> str:
    """The visible text of an HTML fragment, whitespace collapsed (``sep`` replaces each tag).

    Typographic apostrophes, which the site prints for ``'``, are read as ``'``.
    """
    return " ".join(html.unescape(re.sub(r"<[^>]+>", sep, fragment)).replace("\u2019", "'").split())


def _chromium(tmp_path: Path, page: Path) -> str:
    """The DOM that headless Chromium builds from ``page`` (its scripts run)."""
    if not CHROMIUM.exists():
        pytest.fail("the site tests need Debian's chromium: apt-get install -y chromium")
    profile = tmp_path / f"profile-{len(list(tmp_path.iterdir()))}"  # a fresh profile per run
    cmd = [str(CHROMIUM), *FLAGS, f"--user-data-dir={profile}", "--dump-dom", page.as_uri()]
    return subprocess.run(cmd, check=True, capture_output=True, text=True, timeout=120).stdout


def _title(script: Path) -> str:
    """A gallery script's title: the first line of its docstring."""
    doc = ast.get_docstring(ast.parse(script.read_text(encoding="utf-8")))
    assert doc, f"{script.name} needs a docstring whose first line is its title"
    return doc.splitlines()[0].strip()


def test_the_public_api_is_small():
    names = public_names()
    assert len(names) <= MAX_PUBLIC_NAMES, sorted(names)


def test_every_public_name_is_in_the_api_reference(site):
    page = (site / "docs" / "api.html").read_text(encoding="utf-8")
    documented = re.findall(r'<dt class="sig sig-object py" id="(ipcverify(?:\.\w+)*)\.(\w+)">', page)
    assert all(not any(p.startswith("_") for p in m.split(".")) for m, _ in documented), documented
    missing = sorted(set(public_names()) - {name for _, name in documented})
    assert not missing, f"not in docs/api.rst: {missing}"


def test_the_gallery_ran_every_example(site):
    """Each script has its page, with its title, the output it printed and a figure it drew."""
    assert len(EXAMPLES) >= 5
    index = (site / "docs" / "auto_examples" / "index.html").read_text(encoding="utf-8")
    for script in EXAMPLES:
        page = (site / "docs" / "auto_examples" / f"{script.stem}.html").read_text(encoding="utf-8")
        assert _title(script) in _text(re.search(r"<h1>(.*?)</h1>", page, re.S).group(1))
        assert "sphx-glr-script-out" in page, f"{script.name}: no output, so it did not run"
        assert re.search(r'<img[^>]+src="[^"]*sphx_glr_' + script.stem, page), f"{script.name}: no figure"
        assert f"{script.stem}.html" in index


def test_the_output_folder_opens_on_the_site(site):
    root = (site / "index.html").read_text(encoding="utf-8")
    assert 'http-equiv="refresh" content="0; url=docs/index.html"' in root
    assert "<h1>ipcverify documentation" in (site / "docs" / "index.html").read_text(encoding="utf-8")


def test_every_image_and_page_link_of_the_site_resolves(site):
    """The figures the pages show in raw HTML are copied too (docs/conf.py), and no link is dead."""
    missing = []
    for page in site.rglob("*.html"):
        text = page.read_text(encoding="utf-8")
        targets = re.findall(r'<img[^>]+src="([^"]+)"', text) + re.findall(r'<a[^>]+href="([^"#]+)', text)
        for target in targets:
            if not re.match(r"^[a-z]+:", target) and not (page.parent / target).exists():
                missing.append(f"{page.relative_to(site)}: {target}")
    assert not missing, missing[:20]


def _imports(tree: ast.AST) -> list[tuple[str, list[str]]]:
    """(module, names) of every ``import`` and ``from ... import`` of ipcverify in a module."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("ipcverify"):
            out.append((node.module or "", [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names if a.name.startswith("ipcverify")]
    return out


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.name)
def test_examples_import_public_names_only(script):
    """No gallery example imports a private module, or a name its package does not export."""
    bad = []
    for module, names in _imports(ast.parse(script.read_text(encoding="utf-8"))):
        if any(part.startswith("_") for part in module.split(".")):
            bad.append(module)
            continue
        exported = set(importlib.import_module(module).__all__)
        bad += [f"{module}.{n}" for n in names if n not in exported]
    assert not bad, f"{script.name} imports private names: {bad}"


FENCE = re.compile(r"^```(?:python|py|pycon)\n(.*?)^```", re.S | re.M)
IMPORT = re.compile(r"^(?:>>> |\.\.\. )?\s*(?:from|import)\s+(ipcverify[\w.]*)", re.M)


def test_no_page_example_imports_a_private_module():
    """The Python blocks of the pages (README, docs, proofs) import public modules only."""
    bad = []
    for page in [ROOT / "README.md", *ROOT.glob("docs/*.md"), *ROOT.glob("proofs/*.md")]:
        for block in FENCE.findall(page.read_text(encoding="utf-8")):
            private = [m for m in IMPORT.findall(block) if any(p.startswith("_") for p in m.split("."))]
            bad += [f"{page.name}: {m}" for m in private]
    assert not bad, bad


def test_chromium_shows_the_api_reference(site, tmp_path):
    dom = _chromium(tmp_path, site / "docs" / "api.html")
    text = _text(dom)
    assert "API reference" in text
    assert 'id="ipcverify.contract.calibrate"' in dom and 'id="ipcverify.training.TrainConfig"' in dom
    # numpydoc's sections of a docstring, rendered
    calibrate = dom.split('id="ipcverify.contract.calibrate"', 1)[1].split("</dl>", 1)[0]
    assert "Parameters" in _text(calibrate) and "epsilon" in _text(calibrate)
    # the theme's navigation bar: the site's sections (docs/index.md), this page under "Reference"
    nav = _text(dom.split('class="bd-navbar-elements navbar-nav">', 1)[1].split("</ul>", 1)[0])
    assert nav.split() == ["Tutorials", "How-to", "guides", "Reference", "Explanation", "Results"]
    current = r'<li class="nav-item current active">\s*<a class="nav-link nav-internal" href="([\w.]+)"'
    assert re.findall(current, dom)[:1] == ["reference.html"]


def test_chromium_shows_a_gallery_page(site, tmp_path):
    script = ROOT / "examples" / "plot_certify.py"
    dom = _chromium(tmp_path, site / "docs" / "auto_examples" / f"{script.stem}.html")
    text = _text(dom)
    assert _title(script) in text
    assert "from ipcverify import calibrate, certify, example, train" in _text(dom, "")  # the code
    assert "sphx-glr-script-out" in dom and "CERTIFIED" in text  # the verdict it printed
    img = re.search(r'<img[^>]+src="([^"]*sphx_glr_plot_certify_001[^"]*)"', dom)
    assert img and (site / "docs" / "auto_examples" / img.group(1)).resolve().exists()
