#!/usr/bin/env bash
# Side by side with shared/bench-ref in one run: alternates springref and `softatlas bench sim`
# on the same meshes ROUNDS times and prints one JSON object with the best (min) and median of
# each, and the ratio. Usage:
#   bench/compare_ref.sh BUILD_DIR MODEL [ROUNDS] [extra softatlas bench sim args...] -- MESH...
set -euo pipefail
BUILD=${1:?build dir}; MODEL=${2:?model}; ROUNDS=${3:-5}; shift 3 || true
EXTRA=(); while [ $# -gt 0 ] && [ "$1" != "--" ]; do EXTRA+=("$1"); shift; done; shift || true
MESHES=("$@")
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REF_SRC=${SOFTATLAS_BENCH_REF:-$HERE/../../shared/bench-ref}
REF=$("$REF_SRC/build.sh" "$BUILD/bench-ref" | tail -n 1)
REF_MODEL=$MODEL; [ "$MODEL" = nmsm ] || REF_MODEL=tmsm
ours=(); refs=()
for _ in $(seq "$ROUNDS"); do
  refs+=("$("$REF" "${MESHES[@]}" --model "$REF_MODEL" --steps 500 | python3 -c 'import json,sys; print(json.load(sys.stdin)["us_per_step_median"])')")
  ours+=("$("$BUILD/bin/softatlas" bench sim --mesh "${MESHES[@]}" --model "$MODEL" --steps 500 --json "${EXTRA[@]}" | python3 -c 'import json,sys; print(json.load(sys.stdin)["us_per_step_median"])')")
done
python3 - "$MODEL" "${EXTRA[*]:-}" "${refs[*]}" "${ours[*]}" <<'PY'
import json, statistics, sys
model, extra, refs, ours = sys.argv[1], sys.argv[2], [float(x) for x in sys.argv[3].split()], [float(x) for x in sys.argv[4].split()]
print(json.dumps({"model": model, "softatlas_args": extra, "rounds": len(refs),
  "bench_ref_us_min": min(refs), "bench_ref_us_median": statistics.median(refs),
  "softatlas_us_min": min(ours), "softatlas_us_median": statistics.median(ours),
  "ratio_min": min(ours) / min(refs), "ratio_median": statistics.median(ours) / statistics.median(refs)}))
PY
