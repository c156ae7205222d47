#!/usr/bin/env bash
# Blender imports every example's BVH as we wrote it: frame count, every joint and the hand at a
# contact frame within 1 mm of our forward kinematics (docs/bvh.md, "The Blender check").
#
# usage: scripts/check_blender.sh [OUT_DIR]    (default: a fresh temporary folder)
# Installs Blender from the system's packages (apt-get) when `blender` is not on PATH.
# Exit status: 0 when every file passes, 1 when one fails.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PY="${PYTHON:-python3}"
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

# The CLI writes OUT/<stem>.<task>.bvh once it has the bvh target; until then the helper emits.
COMPILE_HELP="$("$PY" -m mtlc compile --help 2>/dev/null || true)"
if grep -Eq -- "--target \{[^}]*bvh" <<<"$COMPILE_HELP"; then
    EMIT=""
else
    EMIT="--emit"
fi

for mtask in examples/*.mtask; do
    if [ -z "$EMIT" ]; then
        compile_log="$OUT/$(basename "$mtask" .mtask).compile.log"
        if ! "$PY" -m mtlc compile "$mtask" --target bvh -o "$OUT" >"$compile_log" 2>&1; then
            cat "$compile_log" >&2
            echo "FAIL $mtask does not compile" >&2
            exit 1
        fi
    fi
    "$PY" scripts/blender_check_bvh.py expect "$mtask" "$OUT" $EMIT
done

status=0
checked=0
for bvh in "$OUT"/*.bvh; do
    expected="${bvh%.bvh}.expected.json"
    log="${bvh%.bvh}.blender.log"
    if blender --background --factory-startup --python-exit-code 1 \
        --python scripts/blender_check_bvh.py -- "$bvh" "$expected" >"$log" 2>&1; then
        grep -E "frames expected; contact frame" "$log" || true
        echo "ok   $(basename "$bvh")"
    else
        grep -E "^FAIL|Error|Traceback" "$log" >&2 || tail -20 "$log" >&2
        echo "FAIL $(basename "$bvh") (log: $log)" >&2
        status=1
    fi
    checked=$((checked + 1))
done

if [ "$checked" -eq 0 ]; then
    echo "no BVH file was made" >&2
    exit 1
fi
echo "$checked BVH files checked in Blender $(blender --version 2>/dev/null | head -1 | cut -d' ' -f2)"
exit "$status"
