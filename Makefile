# Shortcuts; each target calls the stdlib-only scripts, which create and reuse .venv.
.PHONY: demo test lab bench clean
demo:
	python3 scripts/demo
test:
	python3 scripts/test
lab:
	python3 scripts/lab
bench:
	python3 scripts/_venv.py && .venv/bin/python benchmarks/bench_ch03.py
clean:
	rm -rf .venv cvkit-demo autograders/release autograders/submitted autograders/autograded autograders/feedback autograders/*.db
