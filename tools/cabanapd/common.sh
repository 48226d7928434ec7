# Sourced by the side-by-side scripts in this folder: the arguments they share and the peak RSS
# of a /usr/bin/time -v log. After `cabanapd_args DEFAULT_WORK_DIR USAGE_LINES "$@"`: here, repo,
# cabana_exe, cabana_json, work and threads are set.
cabanapd_args() {
  local default_work=$1 usage=$2
  shift 2
  here=$(cd "$(dirname "${BASH_SOURCE[1]}")" && pwd)
  repo=$(cd "$here/../.." && pwd)
  [[ $# -ge 2 ]] || { sed -n "$usage" "${BASH_SOURCE[1]}" >&2; exit 2; }
  cabana_exe=$(readlink -f "$1")
  cabana_json=$(readlink -f "$2")
  work=$(readlink -m "${3:-$default_work}")
  threads=${THREADS:-2}
}

peak_mib() { awk -F: '/Maximum resident/ {printf "%.0f", $2 / 1024}' "$1"; }
