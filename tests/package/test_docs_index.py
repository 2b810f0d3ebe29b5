"""docs/README.md, the documentation's index, links every page of docs/ (a new page must be added there), and
every page it links exists."""
from __future__ import annotations

import re

from tests.conftest import REPO

DOCS = REPO / "docs"


def test_the_docs_index_links_every_page_and_only_pages_that_exist():
    linked = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", (DOCS / "README.md").read_text())
    pages = {path.name for path in DOCS.glob("*.md")} - {"README.md"}
    assert pages <= set(linked), f"not in docs/README.md: {sorted(pages - set(linked))}"
    assert all((DOCS / target).exists() for target in linked), [t for t in linked if not (DOCS / t).exists()]
