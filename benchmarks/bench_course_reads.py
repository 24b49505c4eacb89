"""What a grading run costs after its last grade, in a large course: the exports, the item
analysis, the class notes and the leaderboard read every graded submission of every chapter.

    python benchmarks/bench_course_reads.py [--students 100] [--course DIR]

It grades the demo course (every chapter, the three sample students; or takes the graded course
``--course`` names), makes ``--students`` more students by copying the sample students'
submissions, autograded notebooks and feedback (hard links) and their grades in the gradebook,
then times the reads once, as ``cvkit course grade`` does them at its end. Nothing is graded
again: the figure is the reads alone, the part that grows with the class and the semester.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

TEMPLATES = ("sample_complete", "sample_mistakes")


def graded_demo(folder: Path) -> None:
    subprocess.run([sys.executable, "-m", "cvkit", "demo", "--all", "--dir", str(folder)], check=True,
                   stdout=subprocess.DEVNULL)


def clone_students(course: Path, count: int) -> None:
    """``count`` students more, each a copy of a sample student (files hard-linked, grades copied)."""
    from nbgrader.api import Gradebook

    with Gradebook(f"sqlite:///{course / 'gradebook.db'}") as gradebook:
        assignments = [a.name for a in gradebook.assignments]
        for index in range(count):
            student, template = f"clone{index:03d}", TEMPLATES[index % 2]
            gradebook.update_or_create_student(student)
            for assignment in assignments:
                if not (course / "submitted" / template / assignment).is_dir():
                    continue
                for kind in ("submitted", "autograded", "feedback"):
                    if (course / kind / template / assignment).exists():
                        shutil.copytree(course / kind / template / assignment, course / kind / student / assignment,
                                        copy_function=os.link)
                original = gradebook.find_submission(assignment, template)
                copy = gradebook.add_submission(assignment, student, timestamp=original.timestamp)
                grades = {(nb.name, g.name): g for nb in original.notebooks for g in nb.grades}
                for notebook in copy.notebooks:
                    for grade in notebook.grades:
                        source = grades[(notebook.name, grade.name)]
                        grade.auto_score, grade.manual_score = source.auto_score, source.manual_score
                        grade.needs_manual_grade = source.needs_manual_grade
            gradebook.db.commit()


def time_reads(folder: Path) -> tuple[float, float, int]:
    """Wall and CPU seconds of the reads at the end of a grading run, and the submissions read."""
    from cvkit.course import Course, class_notes, exports, item_analysis, leaderboard

    course = Course(folder)
    submissions = len(course.submissions())
    start, cpu = time.perf_counter(), time.process_time()
    with course.scores_read_once():
        exports.export(course)
        item_analysis.export(course)
        class_notes.annotate_feedback(course)
        leaderboard.publish(course)
    return time.perf_counter() - start, time.process_time() - cpu, submissions


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--students", type=int, default=100)
    parser.add_argument("--course", type=Path, help="a graded demo course to copy (default: grade one now)")
    args = parser.parse_args()
    os.environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"  # nbgrader's alembic
    with tempfile.TemporaryDirectory(prefix="cvkit-reads-") as scratch:
        folder = Path(scratch) / "course"
        if args.course:
            shutil.copytree(args.course, folder, symlinks=True)
        else:
            graded_demo(folder)
        clone_students(folder, args.students)
        wall, cpu, submissions = time_reads(folder)
    print(f"{submissions} graded submissions ({args.students + 3} students): reads at the end of a run "
          f"{wall:.1f} s ({cpu:.1f} s CPU)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
