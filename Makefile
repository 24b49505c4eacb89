# Shortcuts; each target calls the stdlib-only scripts, which create and reuse .venv.
.PHONY: demo test lab bench bench-notebooks bench-grading bench-course-reads clean
demo:
	python3 scripts/demo
test:
	python3 scripts/test
lab:
	python3 scripts/lab
bench:
	python3 scripts/_venv.py && for b in benchmarks/bench_ch*.py; do .venv/bin/python $$b --quick || exit 1; done
bench-notebooks:
	python3 scripts/_venv.py && .venv/bin/python benchmarks/bench_notebooks.py --check
bench-grading:
	python3 scripts/_venv.py && .venv/bin/python benchmarks/bench_grading.py
bench-course-reads:
	python3 scripts/_venv.py && .venv/bin/python benchmarks/bench_course_reads.py
clean:
	rm -rf .venv cvkit-demo artefacts autograders/release autograders/submitted autograders/autograded autograders/feedback autograders/*.db
