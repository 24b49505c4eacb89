"""`cvkit list`: a readable table (columns sized from the data, never running into each other),
computed without drawing any hidden case, from the catalog's index when it is current; course
packages and refused checks shown; --json, --validate, --markdown."""
import json
import subprocess
import sys
import textwrap

from cvkit import catalog, registry
from cvkit.cli import main
from cvkit.grading import Check

from test_registry import course_site  # noqa: F401  (fixture: course packages and providers on sys.path)

HEADERS = ("id", "§", "package", "providers", "check")


def _table(out):
    lines = out.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("id "))
    rows = []
    for line in lines[start + 1:]:
        if line.startswith(("!! ", "plugin ", "course package ")) or line.endswith(("algorithm", "algorithms")) \
                or " algorithms (" in line or " algorithm (" in line:
            break
        rows.append(line)
    return lines[start], rows


def _assert_aligned(header, rows):
    offsets = [header.index(name) for name in HEADERS]
    assert offsets == sorted(offsets) and offsets[0] == 0
    for line in rows:
        for offset in offsets[1:]:
            assert line[offset - 2:offset] == "  ", f"a column runs into the next at {offset}: {line!r}"
            assert line[offset] != " ", f"a cell does not start at its column's offset {offset}: {line!r}"
        cells = [line[a:b].strip() for a, b in zip(offsets, offsets[1:] + [None])]
        assert all(cells), line
    return offsets


def test_columns_start_at_the_same_offset_on_every_line(capsys):
    assert main(["list"]) == 0
    header, rows = _table(capsys.readouterr().out)
    offsets = _assert_aligned(header, rows)
    assert len(rows) == len([a for a in registry.algorithms() if a.package == registry.CVKIT])
    calibrate = next(line for line in rows if line.startswith("calibration.calibrate "))
    assert calibrate[offsets[1]:offsets[2]].strip() == "8.2–8.3.8"  # the widest section keeps its gap
    widest_id = max(len(line[:offsets[1]].rstrip()) for line in rows)
    assert offsets[1] == widest_id + 2  # width from the data


def test_course_packages_widen_the_columns_and_stay_aligned(course_site, tmp_path, monkeypatch, capsys):
    from test_registry import _distribution

    site = tmp_path / "long"
    _distribution(site, "cvkit-a-course-package-with-a-long-name", {"cvkit.algorithms": {"longcourse": "long_pkg"}},
                  {"long_pkg.py": textwrap.dedent("""\
                      import cvkit
                      @cvkit.algorithm("longcourse.an_algorithm_with_a_rather_long_name_indeed", section="12.3.4-12.5.6")
                      def an_algorithm_with_a_rather_long_name_indeed(x):
                          return x
                      """)})
    monkeypatch.syspath_prepend(str(site))
    registry.reload_plugins()
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    header, rows = _table(out)
    offsets = _assert_aligned(header, rows)
    assert offsets[1] == len("longcourse.an_algorithm_with_a_rather_long_name_indeed") + 2
    line = next(r for r in rows if r.startswith("fakecourse.double "))
    assert line[offsets[2]:offsets[3]].strip() == "cvkit-fakecourse"
    assert "reference, fast" in line[offsets[3]:offsets[4]]  # the provider of the course package's id
    assert "1 public, 1 mistakes" in line
    assert "course package 'brokencourse' failed to load" in out and "needs a GPU" in out
    assert "plugin 'typo' failed to load" in out


def test_validate_refuses_a_check_whose_reference_fails(course_site, capsys):
    assert main(["list", "badcheck", "--validate"]) == 1
    out = capsys.readouterr().out
    assert "check broken (see below)" in out
    assert "public case 2 (negative): the reference raised ValueError: x must be >= 0" in out
    assert main(["list", "fakecourse", "--validate"]) == 0
    assert "1 public, 1 mistakes, valid" in capsys.readouterr().out


def test_the_listing_draws_no_hidden_case(monkeypatch, tmp_path, capsys):
    def refuse(self, rng):
        raise AssertionError("cvkit list drew hidden cases")

    monkeypatch.setattr(Check, "hidden_cases", refuse)
    monkeypatch.setattr(catalog, "INDEX_PATH", tmp_path / "missing.json")  # computed live
    assert main(["list"]) == 0
    header, rows = _table(capsys.readouterr().out)
    assert rows and all("check broken" not in line for line in rows)


def test_a_current_index_spares_importing_the_topics(tmp_path, capsys):
    index = tmp_path / "index.json"
    index.write_text(json.dumps(catalog.index()))
    program = (f"import sys, pathlib; from cvkit import catalog; catalog.INDEX_PATH = pathlib.Path({str(index)!r})\n"
               "from cvkit.cli import main; status = main(['list'])\n"
               "print('imported:', sorted(m for m in sys.modules if m.startswith(('cvkit.filters', 'cvkit.grading'))))\n"
               "sys.exit(status)")
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "imported: []" in done.stdout
    assert main(["list"]) == 0  # the same table as computed with the topics imported
    assert done.stdout.split("imported:")[0] == capsys.readouterr().out


def test_json_with_validation(capsys):
    assert main(["list", "filters", "--validate", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    ids = sorted(a.id for a in registry.algorithms() if a.id.startswith("filters."))
    assert [row["id"] for row in rows] == ids
    for row in rows:
        check = registry.get(row["id"]).check
        assert row["public"] == len(check.public_cases()) and row["mistakes"] == len(check.mistakes)
        assert row["check"].endswith(", valid") and row["package"] == "cvkit" and row["providers"][0] == "reference"


def test_markdown_is_the_catalog(capsys):
    assert main(["list", "--markdown"]) == 0
    assert capsys.readouterr().out == catalog.markdown()


def test_an_unknown_namespace_lists_nothing(capsys):
    assert main(["list", "nosuchthing"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "0 algorithms"


def test_every_option_of_every_command_says_what_it_does():
    """`cvkit demo --help` used to list --workers without a word (issue #35)."""
    import argparse

    from cvkit.cli import build_parser

    silent = []

    def walk(parser, path):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, f"{path} {name}")
            elif action.option_strings and not isinstance(action, argparse._HelpAction) and not action.help:
                silent.append(f"{path} {'/'.join(action.option_strings)}")

    walk(build_parser(), "cvkit")
    assert not silent, silent
