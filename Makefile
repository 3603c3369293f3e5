# The two commands of the README, and the documentation site. Each sets up .venv first
# (instant when nothing changed).
.PHONY: setup demo test docs

setup:
	@./launch_scripts/setup_env.sh

demo: setup
	@.venv/bin/fmm demo

# The suite on every core (pytest-xdist, one worker per logical CPU; tests sharing a
# module-scoped fixture stay on one worker, test/conftest.py), its 15 slowest tests printed
# so the time budget stays visible. PYTEST_WORKERS=0 runs it in one process.
# pytest exits 5 when it collected no tests: for this suite that means a broken
# collection, not a pass, so it is reported and turned into a failure.
PYTEST_WORKERS ?= logical
test: setup
	@.venv/bin/python -m pytest -n $(PYTEST_WORKERS) --dist loadgroup --durations=15 $(PYTEST_ARGS); rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test: pytest collected no tests" >&2; exit 1; fi; \
	exit $$rc

# The documentation site into docs/_build/html; any warning fails it (as test/test_docs.py does in CI).
docs: setup
	@.venv/bin/sphinx-build -W --keep-going -n -q -b html docs docs/_build/html
