# pdem: two commands on a fresh machine, `make run` and `make test` (README.md).
# The venv is built from binary wheels only (requirements.lock pins them; the mpich wheel
# brings MPI, the h5py wheel brings HDF5); the repository itself is put on the venv's path.

PY      ?= python3
VENV    := .venv
VPY     := $(VENV)/bin/python
MPIEXEC := $(VENV)/bin/mpiexec
NP      ?= 2
export OMP_NUM_THREADS ?= 1
export MPLBACKEND ?= Agg

PYTEST  := $(VPY) -m pytest -q --timeout=900 --timeout-method=thread
MPI_PYTEST := timeout -k 10 1500 $(MPIEXEC) -n $(NP) $(VPY) -m mpi4py -m pytest -q \
              --timeout=900 --timeout-method=thread --capture=sys

.PHONY: venv run test lint test-quick test-unit test-nojit test-mpi bench validate validation-table box-checks \
	box-thesis-procedure clean

venv: $(VENV)/.done

$(VENV)/.done: requirements.lock pyproject.toml
	$(PY) -m venv $(VENV)
	$(VPY) -m pip install -q --disable-pip-version-check --only-binary :all: -r requirements.lock
	$(VPY) -c "import site, os; open(os.path.join(site.getsitepackages()[0], 'pdem-src.pth'), 'w').write(os.getcwd() + '\n')"
	touch $@

# The main job: the box test jobs/box_test.toml on 2 ranks (README.md, docs/box_test.md).
run: venv
	$(MPIEXEC) -n 2 $(VPY) -m pdem run jobs/box_test.toml --out runs/box_test --fresh

# Lint, serial tests (they also fill the numba cache), the unit tests without JIT, then the MPI
# tests on NP ranks and on 3.
test: venv lint
	$(PYTEST) tests --ignore=tests/mpi
	$(MAKE) --no-print-directory test-nojit
	@if [ -d tests/mpi ]; then \
	  $(MPI_PYTEST) tests/mpi && \
	  timeout -k 10 1500 $(MPIEXEC) -n 3 $(VPY) -m mpi4py -m pytest -q --timeout=900 --timeout-method=thread --capture=sys tests/mpi; \
	fi

lint: venv
	$(VENV)/bin/ruff check pdem tests analysis bench jobs

test-quick: venv lint   # without the tests marked slow (CI runs everything)
	$(PYTEST) tests --ignore=tests/mpi -m "not slow"

test-unit: venv
	$(PYTEST) tests/unit

# The unit tests and the scenes' pieces with numba's JIT off (plain Python: errors a compiled
# kernel hides, such as an index out of bounds, raise; ~20 s); tests marked `jit` need the compiled
# kernels and are skipped.
test-nojit: venv
	NUMBA_DISABLE_JIT=1 $(PYTEST) tests/unit tests/scenes -m "not slow"

test-mpi: venv
	$(MPI_PYTEST) tests/mpi

# The external comparisons (tests marked validate: Yade, analytic solutions), then the validation
# table against the seeds' figures and tables (docs/validation.md).
validate: venv
	$(PYTEST) -m validate tests
	$(MAKE) --no-print-directory validation-table

# docs/validation_table.md from jobs/validation/rows.toml and the result files it names; a campaign
# directory under runs/ with finished members refreshes its committed docs/validation/<name>/values.json
# first. Rows whose files are absent say "not run here" with their campaign file.
validation-table: venv
	$(VPY) -m analysis validate

# Throughput on one rank (1 and 2 threads), then 1 vs 2 MPI ranks, then the start-up time, then the
# full-stiffness box test on 1 and 2 ranks (bench/results.json,
# docs/performance.md)
bench: venv
	$(VPY) -m bench
	$(VPY) -m bench --mpi
	$(VPY) -m bench.startup
	$(VPY) -m bench.box_full

# The box test's calibration and its independent checks against the thesis (docs/box_test.md):
# both campaigns (finished members are skipped, stopped ones resumed), then the table and plots.
# A member that fails (the calibration's `yade` case stops 7 of 10 seeds on purpose) does not stop
# the rest ("-"); the analysis uses the finished members and names a missing case.
box-checks: venv
	-$(VPY) -m pdem campaign run jobs/campaigns/box_calibration.toml
	-$(VPY) -m pdem campaign run jobs/campaigns/box_checks.toml
	$(VPY) -m analysis box-checks runs/box_calibration runs/box_checks --out runs/box_checks/analysis

# The box test prepared the thesis's way (vibrated after the refill, Yade's friction rule, the
# thesis's sleeper), calibrated at E_k 2.8e6 Pa against the thesis and at full stiffness against the
# lab, and the trade-off (docs/box_test.md "Prepared the thesis's way"). The full-stiffness campaign
# is ~1.8 core-hours.
box-thesis-procedure: venv
	-$(VPY) -m pdem campaign run jobs/campaigns/box_thesis_procedure_soft.toml
	-$(VPY) -m pdem campaign run jobs/campaigns/box_thesis_procedure_full.toml
	$(VPY) -m analysis box-thesis-procedure runs/box_thesis_procedure_soft runs/box_thesis_procedure_full \
		--out runs/box_thesis_procedure_full/analysis

clean:
	rm -rf $(VENV) runs bench/cache
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
