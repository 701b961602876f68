#!/usr/bin/env bash
# The traced-sketch protocol (see synthesis/README.md, "Trace"): each shipped exemplar DEM, cropped
# to its centred power-of-two square on its own grid, is traced (`terrasketch trace`), the sketch is
# solved at that size (`terrasketch solve`), and the result is compared with the DEM
# (`terrasketch metrics --reference`): slope-distribution W1 (degrees), spectral slope (radially
# averaged power spectrum, wavelengths extent/4 to 4 cells) and flat fraction (< 2 degrees).
# Usage: scripts/trace_protocol.sh [--keep DIR] [--hillshades DIR] [--trace "ARGS"] [-- SOLVE ARGS...]
#   --keep DIR        keep the sketches, DEM squares and solved heightmaps in DIR (the input of
#                     `cargo run --release -p terrasketch-tools --bin detail_calibrate -- --protocol DIR`)
#   --hillshades DIR  write NAME_dem.png and NAME_traced.png hillshades there
#   --trace "ARGS"    extra arguments for `terrasketch trace` (e.g. "--strokes 200")
#   -- ARGS           extra arguments for `terrasketch solve` (e.g. -- --detail off)
set -euo pipefail
cd "$(dirname "$0")/.."
keep="" shades="" trace_args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --keep) keep="$2"; shift 2 ;;
    --hillshades) shades="$2"; shift 2 ;;
    --trace) read -r -a trace_args <<<"$2"; shift 2 ;;
    --) shift; break ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
solve_args=("$@")
cargo build --release -q -p terrasketch
bin=target/release/terrasketch
if [[ -n "$keep" ]]; then
  mkdir -p "$keep"
  work="$keep"
else
  work="$(mktemp -d)"
  trap 'rm -rf "$work"' EXIT
fi
[[ -n "$shades" ]] && mkdir -p "$shades"
rows="$work/rows.jsonl"
: >"$rows"
for dem in synthesis/exemplars/*.{tif,png}; do
  name="$(basename "${dem%.*}")"
  "$bin" trace "$dem" -o "$work/$name.json" --crop 1024 --dem-output "$work/$name.dem.tif" \
    --json "${trace_args[@]}" >"$work/$name.trace.json"
  side="$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["width"])' "$work/$name.trace.json")"
  "$bin" solve "$work/$name.json" --size "$side" -o "$work/$name.solved.tif" --json \
    "${solve_args[@]}" >"$work/$name.solve.json"
  "$bin" metrics "$work/$name.solved.tif" --reference "$work/$name.dem.tif" --json \
    >"$work/$name.metrics.json"
  if [[ -n "$shades" ]]; then
    "$bin" masks "$work/$name.dem.tif" -o "$work/$name.masks_dem" >/dev/null
    "$bin" masks "$work/$name.solved.tif" -o "$work/$name.masks_traced" >/dev/null
    cp "$work/$name.masks_dem/hillshade.png" "$shades/${name}_dem.png"
    cp "$work/$name.masks_traced/hillshade.png" "$shades/${name}_traced.png"
  fi
  python3 - "$name" "$work/$name.trace.json" "$work/$name.solve.json" "$work/$name.metrics.json" \
    >>"$rows" <<'PY'
import json, sys
name, t, s, m = sys.argv[1], *(json.load(open(p)) for p in sys.argv[2:])
print(json.dumps({"name": name, "trace": t, "solve": s, "metrics": m}))
PY
done
echo "trace args: ${trace_args[*]:-(defaults)}; solve args: ${solve_args[*]:-(defaults)}"
python3 - "$rows" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print("| DEM | square | strokes (v+r) | trace ms | slope W1 (deg) | spectral slope: traced / DEM (diff) | flat fraction: traced / DEM (ratio) |")
print("|---|---|---|---|---|---|---|")
for r in rows:
    t, m = r["trace"], r["metrics"]
    a, ref, c = m["metrics"], m["reference_metrics"], m["comparison"]
    ss, sr = a["spectral_slope"], ref["spectral_slope"]
    ff, fr = a["flat_fraction"], ref["flat_fraction"]
    ratio = f"{ff / fr:.2f}" if fr > 0 else "-"
    print(f"| {r['name']} | {t['width']} | {t['valleys']}+{t['ridges']} | {t['ms_trace']:.0f} | "
          f"{c['slope_wasserstein_deg']:.2f} | {ss:.2f} / {sr:.2f} ({ss - sr:+.2f}) | "
          f"{ff:.3f} / {fr:.3f} ({ratio}) |")
PY
