"""The documentation's relative links resolve, and every proofs page links code and tests that exist."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted(
    [ROOT / "README.md", ROOT / "CHANGELOG.md", *ROOT.glob("docs/*.md"), *ROOT.glob("proofs/*.md")]
)
LINK = re.compile(r"\]\(([^)\s]+)\)|src=\"([^\"]+)\"")


def _targets(page: Path) -> list[str]:
    text = page.read_text(encoding="utf-8")
    out = []
    for a, b in LINK.findall(text):
        t = (a or b).split("#", 1)[0]
        if t and not re.match(r"^[a-z]+:", t):
            out.append(t)
    return out


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(page):
    missing = [t for t in _targets(page) if not (page.parent / t).exists()]
    # links that leave the repository (e.g. to the shared style guide) are not checked
    missing = [t for t in missing if (page.parent / t).resolve().is_relative_to(ROOT)]
    assert not missing, f"{page.relative_to(ROOT)}: broken links {missing}"


@pytest.mark.parametrize("page", sorted(ROOT.glob("proofs/*.md")), ids=lambda p: p.name)
def test_every_proof_links_its_code_and_its_tests(page):
    targets = [(page.parent / t).resolve() for t in _targets(page)]
    code = [
        t for t in targets if t.is_relative_to(ROOT / "ipcverify") or t.is_relative_to(ROOT / "case_studies")
    ]
    tests = [t for t in targets if t.is_relative_to(ROOT / "tests")]
    assert code and tests, f"{page.name} must link the code that implements it and the test that checks it"
