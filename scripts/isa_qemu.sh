#!/usr/bin/env bash
# The release binary on a CPU without AVX2: starts, and computes the same bits as the
# baseline kernels natively.
#
# qemu-user emulates a Nehalem (SSE4.2, no AVX): install it with
#     apt-get install qemu-user
# Then, from the repository root:
#     bash scripts/isa_qemu.sh            # the pipeline on four scenes (~1 min)
#     bash scripts/isa_qemu.sh --scenes   # and every scene scripts/bit_identical.py knows
#                                         # (bundled, ../shared, public; ~30 min)
# Compares, file by file, what `qemu-x86_64 -cpu Nehalem tstat ...` writes with what the
# same binary writes natively under TSTAT_ISA=baseline: renders (surfaces, a BVH, a
# medium, an NLOS capture), both denoisers and the five NLOS reconstructions. Not part of
# `cargo test` (qemu is an apt package, not a crate); tests/it/isa.rs checks the levels this
# CPU has. Exit status 1 on any difference.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v qemu-x86_64 >/dev/null || { echo "error: qemu-x86_64 not found (apt-get install qemu-user)" >&2; exit 1; }
cargo build --release -q
bin="$PWD/target/release/tstat"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
printf '#!/bin/sh\nexec qemu-x86_64 -cpu Nehalem "%s" "$@"\n' "$bin" > "$tmp/tstat-nehalem"
chmod +x "$tmp/tstat-nehalem"
# The emulated CPU really lacks AVX2: a build pinned to x86-64-v3 dies there (SIGILL).
"$tmp/tstat-nehalem" --version

run_all() { # $1: the tstat command, $2: output folder
  local t=$1 d=$2 v="--volume=-1,1,-1,1,0.5,1.5"
  mkdir -p "$d"
  for s in cbox_spheres bunny cbox_fog; do
    $t render "scenes/$s.xml" --spp 4 --width 24 --bins 40 --out "$d/$s.tstats" >/dev/null 2>&1
  done
  $t denoise "$d/cbox_spheres.tstats" --out "$d/tstat.npy" >/dev/null 2>&1
  $t denoise "$d/cbox_spheres.tstats" --method published --out "$d/published.npy" >/dev/null 2>&1
  $t render scenes/nlos_T.xml --spp 4 --out "$d/T.tstats" >/dev/null 2>&1
  $t nlos reconstruct "$d/T.tstats" --method bp $v --voxels 15,15,9 --out "$d/bp.npy" >/dev/null 2>&1
  for m in fbp pf; do
    $t nlos reconstruct "$d/T.tstats" --method $m --wl-mean 0.2 $v --voxels 15,15,9 --out "$d/$m.npy" >/dev/null 2>&1
  done
  for m in fk lct; do
    $t nlos reconstruct "$d/T.tstats" --method $m $v --voxels 15,15,9 --out "$d/$m.npy" >/dev/null 2>&1
  done
}
TSTAT_ISA=baseline run_all "$bin" "$tmp/native"
run_all "$tmp/tstat-nehalem" "$tmp/nehalem"
status=0
n=0
while IFS= read -r f; do
  rel=${f#"$tmp/native/"}
  n=$((n + 1))
  if ! cmp -s "$f" "$tmp/nehalem/$rel"; then echo "DIFFERS $rel"; status=1; fi
done < <(find "$tmp/native" -name '*.npy' | sort)
echo "$n arrays compared (native baseline against qemu Nehalem): $([ $status = 0 ] && echo 'all the same bits' || echo 'some differ')"
if [ "${1:-}" = "--scenes" ]; then
  printf '#!/bin/sh\nTSTAT_ISA=baseline exec "%s" "$@"\n' "$bin" > "$tmp/tstat-baseline"
  chmod +x "$tmp/tstat-baseline"
  python3 scripts/bit_identical.py --tstat "$tmp/tstat-baseline" --save "$tmp/native.json"
  python3 scripts/bit_identical.py --tstat "$tmp/tstat-nehalem" --timeout 1200 --compare "$tmp/native.json" || status=1
fi
exit $status
