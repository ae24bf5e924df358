#!/usr/bin/env bash
# One entry point for a fresh machine (Python 3.11, gcc, apt):
#   ./run.sh demo   set up, then trace -> identify -> FMU -> validate -> report
#   ./run.sh test   set up, then the whole test suite
#   ./run.sh bench  set up, then the benchmarks (JSON in benchmarks/results/, pages in docs/results/);
#                   ./run.sh bench NAME [ARGS] runs benchmarks/bench_NAME.py alone
# Everything the project needs is installed here: the venv, the Python packages
# and, through apt, the system packages the tests use (TBB for the ecos engine,
# valgrind, the mingw-w64 cross compiler for win64 FMU binaries).
set -euo pipefail
cd "$(dirname "$0")"
VENV=.venv
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3

apt_install() {
    local missing=()
    for pkg in "$@"; do
        dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
    done
    [ ${#missing[@]} -eq 0 ] && return 0
    local sudo=""
    [ "$(id -u)" -ne 0 ] && sudo="sudo"
    echo "run.sh: apt-get install ${missing[*]}"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

setup() {
    if [ ! -x "$VENV/bin/python" ]; then
        "$PY" -m venv "$VENV"
    fi
    # a new stamp (reinstall, which rebuilds the compiled core) when the project or the C changes
    local stamp="$VENV/.installed-$(cat pyproject.toml src/fdid_fmi/fmu_templates/*.[ch] \
        src/fdid_fmi/kernel_ext/* | sha1sum | cut -c1-12)-$1"
    if [ ! -f "$stamp" ]; then
        "$VENV/bin/python" -m pip install -q --upgrade pip
        if [ "$1" = test ]; then
            "$VENV/bin/python" -m pip install -q -e ".[test]"
        else
            "$VENV/bin/python" -m pip install -q -e .
        fi
        touch "$stamp"
    fi
}

cmd=${1:-demo}
shift || true
case "$cmd" in
    demo)
        setup demo
        # fdid demo's own folders: out/demo/virtual, out/demo/emps (one shared folder left the
        # virtual run's plan.html beside the EMPS run's files)
        "$VENV/bin/fdid" demo "$@"
        ;;
    test)
        apt_install libtbb12 valgrind gcc-mingw-w64-x86-64
        setup test
        # pytest -n 2 keeps both cores busy: BLAS threads on top of its two processes only compete
        # for them (session 32: 1106 CPU-s and 9 min 22 s with OpenBLAS's own threads, 880 CPU-s
        # and 7 min 25 s with one per process); fdid's own pools and the fdid command do the same
        # (src/fdid_fmi/workers.py)
        export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1} OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} \
            MKL_NUM_THREADS=${MKL_NUM_THREADS:-1}
        "$VENV/bin/python" -m pytest -n 2 --dist worksteal -q --durations=15 "$@"
        ;;
    bench)
        setup test
        # the peer of the EMPS page (a SysIdentPy NARX); its release pins an older numpy than the
        # project's, and its own dependencies (numpy, scipy, matplotlib) are installed already
        "$VENV/bin/python" -c "import sysidentpy" 2>/dev/null ||
            "$VENV/bin/python" -m pip install -q --no-deps "sysidentpy>=0.9"
        # ./run.sh bench            every benchmark with its defaults
        # ./run.sh bench NAME ARGS  one benchmark (benchmarks/bench_NAME.py) with its own options;
        #                           options differ between scripts, so they are never given to all
        # Run with its default options a benchmark also writes its page docs/results/NAME.md
        # (benchmarks/publish.py); then the README's results table is rebuilt from those pages.
        if [ $# -eq 0 ]; then
            for b in benchmarks/bench_*.py; do "$VENV/bin/python" "$b"; done
        elif [ -f "benchmarks/bench_$1.py" ]; then
            b=$1
            shift
            "$VENV/bin/python" "benchmarks/bench_$b.py" "$@"
        else
            echo "run.sh: no benchmark '$1'; one of: $(ls benchmarks/bench_*.py | sed 's#.*/bench_##; s#\.py$##' | tr '\n' ' ')" >&2
            exit 2
        fi
        "$VENV/bin/python" benchmarks/readme_table.py
        ;;
    *)
        echo "usage: ./run.sh demo|test|bench [args]" >&2
        exit 2
        ;;
esac
