# The two commands of the README. Both set up .venv first (instant when nothing changed).
.PHONY: setup demo test

setup:
	@./launch_scripts/setup_env.sh

demo: setup
	@.venv/bin/fmm demo

# pytest exits 5 when it collected no tests: for this suite that means a broken
# collection, not a pass, so it is reported and turned into a failure.
test: setup
	@.venv/bin/python -m pytest $(PYTEST_ARGS); rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test: pytest collected no tests" >&2; exit 1; fi; \
	exit $$rc
