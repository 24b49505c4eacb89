"""The catalog in the project: docs/catalog.md and the index of `cvkit list`, generated from the
registry, are current; the catalog lists every algorithm with its section, signature,
conventions and building blocks."""
import re

import pytest

from cvkit import catalog, registry


@pytest.fixture(scope="module")
def rows():
    return catalog.entries([a for a in registry.algorithms() if a.package == registry.CVKIT])


@pytest.fixture(scope="module")
def text(rows):
    return catalog.markdown(rows)


def test_committed_files_are_current(rows, text):
    generated = {catalog.CATALOG_PATH: text, catalog.INDEX_PATH: catalog._index_text(catalog.index(rows))}
    for path, fresh in generated.items():
        assert path.is_file(), f"{path} is missing: run `{catalog.REGENERATE}`"
        assert path.read_text(encoding="utf-8") == fresh, (
            f"{path.relative_to(catalog.PACKAGE_DIR.parent)} is out of date: run `{catalog.REGENERATE}` "
            "and commit the result")


def _table_rows(text):
    return [line for line in text.splitlines() if line.startswith("| ") and not line.startswith(("| id ", "|---"))]


def _cells(line):
    return [cell.strip() for cell in re.split(r"(?<!\\)\|", line)[1:-1]]


def test_every_algorithm_once_with_section_signature_and_summary(rows, text):
    lines = {_cells(line)[0]: _cells(line) for line in _table_rows(text)}
    assert len(lines) == len(_table_rows(text)) == len(rows) > 100
    for row in rows:
        cells = lines[row["id"]]
        assert len(cells) == 5, cells  # id, §, signature, what it computes, building blocks
        assert cells[1] == row["section"] and cells[2] == f"`{row['signature']}`".replace("|", "\\|")
        assert cells[3], f"{row['id']} has no summary (first paragraph of its docstring)"
        assert row["check_error"] is None, f"{row['id']}: {row['check_error']}"
    gaussian = lines["filters.gaussian"]
    assert gaussian[2] == "`(image, sigma, border='reflect101')`" and gaussian[1] == "3.9.1"


def test_building_blocks_come_from_the_checks(rows, text):
    lines = {_cells(line)[0]: _cells(line) for line in _table_rows(text)}
    with_blocks = [row for row in rows if row["allowed"]]
    assert with_blocks
    for row in with_blocks:
        assert lines[row["id"]][4].startswith(", ".join(row["allowed"]))
    assert lines["camera.project"][4] == "camera.from_homogeneous, camera.to_homogeneous"
    assert lines["filters.mean_kernel"][4] == "—"


def test_each_topic_has_its_section_with_its_conventions(text):
    for topic in registry.topic_modules():
        heading = next((line for line in text.splitlines() if line.startswith(f"## `cvkit.{topic}` — ")), None)
        assert heading, f"no section for cvkit.{topic}"
        assert re.search(r"Chapters? \d", heading), heading
    assert "## Conventions (every topic)" in text
    filters_section = text.split("## `cvkit.filters`")[1].split("\n## ")[0]
    assert "never modifies its input" in filters_section  # from the topic module's docstring
    assert "```" not in text.split("## Conventions")[1] and ">>>" not in text  # no doctests, no RST tables
    assert "``" not in text and ":func:" not in text


def test_chapters_in_order(text):
    chapters = [int(re.search(r"Chapters? (\d+)", line).group(1)) for line in text.splitlines()
                if line.startswith("## `cvkit.")]
    assert chapters == sorted(chapters)


def test_catalog_ids_parse_as_the_notebook_tests_read_them(rows, text):
    """tests/lectures/test_notebooks.py reads the ids of the catalog's tables (first column)."""
    ids = [_cells(line)[0] for line in _table_rows(text)]
    assert all(re.fullmatch(r"[a-z_]+\.[A-Za-z_][A-Za-z0-9_]*", i) for i in ids)
    assert sorted(ids) == sorted(row["id"] for row in rows)


def test_stale_catalog_is_detected_and_rewritten(tmp_path, monkeypatch):
    monkeypatch.setattr(catalog, "CATALOG_PATH", tmp_path / "docs" / "catalog.md")
    monkeypatch.setattr(catalog, "INDEX_PATH", tmp_path / "_catalog_index.json")
    with pytest.raises(FileNotFoundError, match="checkout"):
        catalog.write()
    (tmp_path / "docs").mkdir()
    assert set(catalog.stale()) == {catalog.CATALOG_PATH, catalog.INDEX_PATH}
    assert catalog.main(["--check"]) == 1
    assert set(catalog.write()) == {catalog.CATALOG_PATH, catalog.INDEX_PATH}
    assert catalog.stale() == [] and catalog.main(["--check"]) == 0
    catalog.CATALOG_PATH.write_text("edited by hand\n")
    assert catalog.stale() == [catalog.CATALOG_PATH]


def test_the_index_fingerprint_covers_every_registration(rows):
    """The index is trusted while the fingerprint holds: it must see every @algorithm(...)."""
    found = []
    for topic in registry.topic_modules():
        for path in sorted((catalog.PACKAGE_DIR / topic).rglob("*.py")):
            found += [re.search(r"\"([a-z_]+\.[A-Za-z_0-9]+)\"", d).group(1)
                      for d in catalog._DECORATOR.findall(path.read_text(encoding="utf-8"))]
    assert sorted(found) == sorted(row["id"] for row in rows)
