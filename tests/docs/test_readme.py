"""The README runs as written: every fenced block, in order, in one temporary working directory
(the rules are those of ``tests/doc_blocks.py``).  What the README used to hold beyond its quick
starts lives on the site, whose pages ``tests/docs/test_site.py`` runs the same way."""

from __future__ import annotations

import pytest

from doc_blocks import ROOT, run_documents, snippets_write_what_they_say

pytestmark = pytest.mark.slow

README = ROOT / "README.md"


@pytest.fixture(scope="module")
def readme_run(tmp_path_factory):
    return run_documents([README], tmp_path_factory.mktemp("readme"))


def test_every_block_runs(readme_run):
    if readme_run.failure is not None:
        pytest.fail(f"{type(readme_run.failure).__name__}: {readme_run.failure}")


def test_snippets_write_what_they_say(readme_run):
    snippets_write_what_they_say(readme_run)
