#!/usr/bin/env bash
# Runs every libFuzzer target of tests/fuzz for SECONDS each, from a scratch copy of its seed
# corpus (tests/fuzz/corpus/<target>), so a run never writes into the repository.
#
#   bash tools/fuzz.sh SECONDS [BUILD_DIR]      BUILD_DIR: a tree configured with PERIDOT_FUZZ=ON
#                                               (default build/asan: the asan preset)
#
# Environment: FUZZ_TARGETS="fuzz_vtu fuzz_gmsh" runs only those; FUZZ_PARALLEL=2 runs two at
# a time (one core each). Prints per target the executions, the coverage (cov: and ft: of
# libFuzzer's final stats line) and the findings, then a one-line summary per target; exits 1
# on any finding (a crash, a sanitizer report, an uncaught exception, a leak, a hang past 10 s
# or an allocation past 2 GiB), with the reproducer kept and its path printed, 2 on misuse.
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
root=$PWD

seconds=${1:-}
build=${2:-build/asan}
if ! [[ $seconds =~ ^[0-9]+$ ]] || (( seconds < 1 )); then
  echo "usage: tools/fuzz.sh SECONDS [BUILD_DIR]" >&2
  exit 2
fi
[[ $build == /* ]] || build=$root/$build
targets=${FUZZ_TARGETS:-fuzz_deck fuzz_vtu fuzz_checkpoint fuzz_gmsh}
parallel=${FUZZ_PARALLEL:-1}

# Longest input per target: a little above the largest seed, so mutations stay near real files.
max_len() {
  case $1 in
    fuzz_deck) echo 16384 ;;
    fuzz_vtu) echo 8192 ;;
    fuzz_checkpoint) echo 16384 ;;
    fuzz_gmsh) echo 8192 ;;
    *) echo 4096 ;;
  esac
}

for t in $targets; do
  if [[ ! -x $build/tests/fuzz/$t ]]; then
    echo "fuzz: $build/tests/fuzz/$t is missing: configure $build with -DPERIDOT_FUZZ=ON (the asan preset does) and build it" >&2
    exit 2
  fi
  if [[ ! -d tests/fuzz/corpus/$t ]]; then
    echo "fuzz: tests/fuzz/corpus/$t is missing" >&2
    exit 2
  fi
done

work=$(mktemp -d "${TMPDIR:-/tmp}/peridot_fuzz.XXXXXX")
export OMP_NUM_THREADS=1
export LSAN_OPTIONS="suppressions=$root/tests/fuzz/lsan.supp"
export UBSAN_OPTIONS="print_stacktrace=1"
# Reports with function names and lines (clang-19 ships no llvm-symbolizer-19 on Debian 12).
if [[ -z ${ASAN_SYMBOLIZER_PATH:-} ]]; then
  for s in llvm-symbolizer-19 llvm-symbolizer; do
    if command -v "$s" >/dev/null; then
      export ASAN_SYMBOLIZER_PATH=$(command -v "$s")
      break
    fi
  done
fi

# One target: fuzz in $work/<target>, leave its log and a result line in there.
run_one() {
  local t=$1 dir=$work/$1
  mkdir -p "$dir/artifacts"
  cp -r "tests/fuzz/corpus/$t" "$dir/corpus"
  cp -r tests/fuzz/files "$dir/files"
  local rc=0
  # The deck target resolves mesh files against PERIDOT_FUZZ_FILES; the others ignore it.
  (cd "$dir" && PERIDOT_FUZZ_FILES="$dir/files" TMPDIR="$dir" "$build/tests/fuzz/$t" \
     -max_total_time="$seconds" -max_len="$(max_len "$t")" -rss_limit_mb=2048 -timeout=10 \
     -print_final_stats=1 -artifact_prefix="$dir/artifacts/" "$dir/corpus") >"$dir/log" 2>&1 || rc=$?
  echo "$rc" >"$dir/rc"
}

running=0
for t in $targets; do
  echo "fuzz: $t for ${seconds} s ..."
  run_one "$t" &
  running=$((running + 1))
  if (( running >= parallel )); then
    wait -n
    running=$((running - 1))
  fi
done
wait

status=0
summary=()
for t in $targets; do
  dir=$work/$t
  rc=$(cat "$dir/rc")
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$dir/log" | tail -1)
  # The last status line (DONE, or the last pulse/NEW before a finding) has the final cov/ft.
  line=$(grep -E '^#[0-9]+.*cov: ' "$dir/log" | tail -1)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$line")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$line")
  corpus_in=$(find "tests/fuzz/corpus/$t" -type f | wc -l)
  corpus_out=$(find "$dir/corpus" -type f | wc -l)
  # slow-unit-* only reports an input above 10 s... which -timeout=10 already turns into a
  # timeout-*: every artifact is a finding.
  mapfile -t found < <(find "$dir/artifacts" -type f | sort)
  findings=${#found[@]}
  if [[ $rc != 0 ]] && (( findings == 0 )); then findings=1; fi
  echo
  echo "=== $t: ${execs:-?} executions, cov ${cov:-?}, ft ${ft:-?}, corpus ${corpus_in} -> ${corpus_out}, findings ${findings} (exit ${rc})"
  if (( findings > 0 )); then
    status=1
    # The report: the sanitizer's or libFuzzer's lines from the first error on.
    first=$(grep -n -m1 -E 'ERROR|runtime error:|breaks its promise' "$dir/log" | cut -d: -f1)
    [[ -n $first ]] && sed -n "${first},\$p" "$dir/log" | grep -v 'external symbolizer' | head -80
    for f in "${found[@]}"; do echo "reproducer: $f  (replay: $build/tests/fuzz/$t $f)"; done
    echo "full log: $dir/log"
  fi
  summary+=("$(printf '%-16s %10s execs  cov %6s  ft %7s  findings %s' "$t" "${execs:-?}" "${cov:-?}" "${ft:-?}" "$findings")")
done

echo
echo "fuzz summary (${seconds} s per target):"
printf '  %s\n' "${summary[@]}"
if (( status == 0 )); then
  rm -rf "$work"
else
  echo "fuzz: findings above; logs and reproducers kept in $work"
fi
exit $status
