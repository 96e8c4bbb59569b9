#!/usr/bin/env bash
# Peak memory of `tstat merge` against the number of shards and the film size.
#
#   scripts/merge_memory.sh [CASE...]      (CASE: few, many, large; default all)
#
# Renders, with `--shard I/N`, (few) 4 and (many) 128 shards of a 64x64x500 cbox film
# and (large) 2 shards of a 256x256x1000 film (2 spp each), then merges each with the default
# band memory under GNU time and prints the peak resident set (and the bundles' sizes
# on disk, for scale). Needs ~25 GB of free disk at its peak (each set is deleted after
# its merge). Not part of CI. Output: docs/results/merge_memory.md.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
WORK=${TSTAT_MERGE_WORK:-/tmp/tstat-merge-memory}
TSTAT=$ROOT/target/release/tstat
[ -x "$TSTAT" ] || (cd "$ROOT" && cargo build --release)
SCENE=$ROOT/scenes/cbox.xml

run_case() { # name shards width bins
  local name=$1 n=$2 w=$3 t=$4
  local dir=$WORK/$name
  rm -rf "$dir"; mkdir -p "$dir"
  for ((i = 0; i < n; i++)); do
    "$TSTAT" render "$SCENE" --shard "$i/$n" --out "$dir/shard-{shard}.tstats" \
      --spp $((2 * n)) --width "$w" --bins "$t" --bin-width-opl 0.05 --seed 3 >/dev/null 2>&1
  done
  local size
  size=$(du -sh "$dir" | cut -f1)
  /usr/bin/time -v "$TSTAT" merge "$dir"/shard-*.tstats --out "$dir/merged.tstats" \
    2> "$dir/time.txt" >/dev/null
  local rss secs
  rss=$(awk -F': ' '/Maximum resident set size/ {print $2}' "$dir/time.txt")
  secs=$(awk -F': ' '/Elapsed \(wall clock\)/ {print $2}' "$dir/time.txt")
  echo "| $n shards of ${w}x${w}x${t} | $size | $((rss / 1024)) MB | $secs |"
  rm -rf "$dir"
}

echo "| merge | shards on disk | peak RSS | wall (m:ss) |"
echo "|---|---|---|---|"
for c in "${@:-few many large}"; do
  for c1 in $c; do
    case $c1 in
      few) run_case few 4 64 500 ;;
      many) run_case many 128 64 500 ;;
      large) run_case large 2 256 1000 ;;
      *) echo "unknown case $c1" >&2; exit 2 ;;
    esac
  done
done
