#!/usr/bin/env bash
# The realism pass's measurement protocol (see synthesis/README.md, "Measured"):
#  1. Scott & Dodgson's guide reproduction, leave-one-out, on every shipped exemplar: one table per
#     DEM (real, 16x guide, refined): slope W1, roughness_cv, flat_fraction, axis_ratio, spectral
#     slope, pits > 10 m per 100 km^2, trenches.
#  2. examples/range.json refined at 1024^2: axis_ratio, trenches, constraint error, time.
# Usage: scripts/guide_protocol.sh [SEED] [HILLSHADE_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
seed="${1:-1}"
shades="${2:-}"
cargo build --release -q -p terrasketch -p terrasketch-tools --bins
args=(--seed "$seed")
if [[ -n "$shades" ]]; then
  mkdir -p "$shades"
  args+=(--hillshades "$shades")
fi
echo "## Guide reproduction, leave-one-out (seed $seed)"
target/release/guide_protocol "${args[@]}"

echo
echo "## examples/range.json at 1024^2 (seed $seed)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
target/release/terrasketch refine examples/range.json --size 1024 -o "$tmp/range.tif" \
  --seed "$seed" --json >"$tmp/refine.json"
target/release/terrasketch metrics "$tmp/range.tif" --json >"$tmp/metrics.json"
python3 - "$tmp/refine.json" "$tmp/metrics.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
m = json.load(open(sys.argv[2]))["metrics"]
rows = [
    ("axis_ratio", f"{m['axis_ratio']:.2f}", "<= 1.25"),
    ("trenches", m["trenches"], "<= 3"),
    ("flat_fraction", f"{m['flat_fraction']:.3f}", ""),
    ("roughness_cv", f"{m['roughness_cv']:.2f}", ""),
    ("constraint_max_excess_m (beyond each cell's tolerance)", f"{r['constraint_max_excess_m']:.2e}",
     "0"),
    ("constraint_max_error_m", f"{r['constraint_max_error_m']:.2f}",
     f"<= largest tolerance ({r['constraint_tolerance_max_m']:.2f} m)"),
    ("pits_after_per_100km2", f"{r['pits_after_per_100km2']:.1f}",
     f"<= exemplars' {r['exemplar_pits_per_100km2']:.1f}"),
    ("slope_w1_to_exemplars (diffusion's)",
     f"{r['slope_w1_to_exemplars']:.2f} ({r['slope_w1_diffusion_to_exemplars']:.2f})", ""),
    ("ms_total", f"{r['ms_total']:.0f}", "<= 10000"),
]
print("| measure | value | target |\n|---|---|---|")
for k, v, t in rows:
    print(f"| {k} | {v} | {t} |")
PY
if [[ -n "$shades" ]]; then
  target/release/guide_protocol --hillshade-of "$tmp/range.tif" "$shades/range_1024_seed$seed.png"
fi
