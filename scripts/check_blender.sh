#!/usr/bin/env bash
# Blender imports every example's BVH as we meant it: frame count and rate, feet on the ground,
# every hand at its goal site at each TO end and every joint at the first, within 1 mm of what the
# compile's own IR says (docs/bvh.md, "The Blender check").
#
# usage: scripts/check_blender.sh [--compiled] [OUT_DIR]    (default: a fresh temporary folder)
# --compiled: OUT_DIR already holds every example's BVH and IR (the test suite writes them from
# the compiles its other tests share); check those instead of compiling the examples again.
# Installs Blender from the system's packages (apt-get) when `blender` is not on PATH.
# Exit status: 0 when every file passes, 1 when one fails.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PY="${PYTHON:-python3}"
COMPILED=0
if [ "${1:-}" = "--compiled" ]; then
    COMPILED=1
    shift
fi
OUT="${1:-$(mktemp -d -t mtlc-blender.XXXXXX)}"
mkdir -p "$OUT"
cd "$ROOT"

if ! command -v blender >/dev/null 2>&1; then
    echo "blender not found: installing it with apt-get (several minutes)" >&2
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq blender >/dev/null
fi

# Compile every example (BVH and IR), then derive Blender's expectations from each IR.
if [ "$COMPILED" -eq 0 ]; then
    for mtask in examples/*.mtask; do
        compile_log="$OUT/$(basename "$mtask" .mtask).compile.log"
        if ! "$PY" -m mtlc compile "$mtask" --target all -o "$OUT" >"$compile_log" 2>&1; then
            cat "$compile_log" >&2
            echo "FAIL $mtask does not compile" >&2
            exit 1
        fi
    done
fi
shopt -s nullglob
irs=("$OUT"/*.ir.json)
if [ "${#irs[@]}" -eq 0 ]; then
    echo "no BVH file was made" >&2
    exit 1
fi
"$PY" scripts/blender_check_bvh.py expect "${irs[@]}"

# One Blender process checks every file (its start-up is most of a small file's cost).
pairs=()
for ir in "${irs[@]}"; do
    base="${ir%.ir.json}"
    pairs+=("$base.bvh" "$base.expected.json")
done
log="$OUT/blender.log"
status=0
blender --background --factory-startup --python-exit-code 1 \
    --python scripts/blender_check_bvh.py -- "${pairs[@]}" >"$log" 2>&1 || status=1
grep -E "^(ok  |FAIL)|frames at .* fps" "$log" || true
if [ "$status" -ne 0 ]; then
    grep -E "Error|Traceback" "$log" >&2 || true
    echo "Blender's check failed (log: $log)" >&2
fi
echo "${#irs[@]} BVH files checked in Blender $(blender --version 2>/dev/null | head -1 | cut -d' ' -f2)"
exit "$status"
