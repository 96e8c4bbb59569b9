#!/usr/bin/env bash
# Runs `tstat cluster slurm` on a real one-node Slurm cluster and checks the result.
#
#   sudo scripts/slurm_test.sh [WORKDIR]      (root: it installs and starts daemons)
#
# 1. Installs Slurm and MUNGE from the distribution's packages when they are missing
#    (`apt-get install -y slurm-wlm munge`; Debian 12 gives Slurm 22.05).
# 2. Writes a one-node slurm.conf (this host, its CPUs and memory; no cgroups, so it
#    also runs in containers), starts munged, slurmctld and slurmd.
# 3. Generates the recipes for cbox (4 shards, 64x64, 100 bins, 64 spp, denoised),
#    submits `sbatch DIR/render.sbatch`, then `sbatch --dependency=afterok:<id>
#    DIR/merge.sbatch` from another folder, and waits.
# 4. Renders the same 4 shards locally (`tstat render --shard I/4`), merges them, and
#    checks every array of the cluster's merged bundle is bit-identical to the local
#    one, and the denoised volume too. Prints PASS or exits non-zero.
#
# Not part of CI (needs root, packages and daemons). Output: docs/results/slurm_test.md.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
WORK=${1:-/tmp/tstat-slurm-test}
TSTAT=$ROOT/target/release/tstat
[ -x "$TSTAT" ] || (cd "$ROOT" && cargo build --release)

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  DEBIAN_FRONTEND=noninteractive apt-get install -y slurm-wlm munge
fi
echo "slurm: $(slurmd -V)"

# --- MUNGE ---------------------------------------------------------------------------
[ -s /etc/munge/munge.key ] || mungekey --create --force
chown munge:munge /etc/munge/munge.key 2>/dev/null || true
chmod 400 /etc/munge/munge.key
mkdir -p /run/munge /var/log/munge /var/lib/munge
chown munge:munge /run/munge /var/log/munge /var/lib/munge 2>/dev/null || true
if ! munge -n >/dev/null 2>&1; then
  if id munge >/dev/null 2>&1; then
    su -s /bin/sh munge -c munged || munged --force
  else
    munged --force
  fi
  sleep 1
fi
munge -n | unmunge >/dev/null

# --- one-node cluster ----------------------------------------------------------------
HOST=$(hostname -s)
CPUS=$(nproc)
MEM_MB=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 1024 ))
mkdir -p /etc/slurm /var/spool/slurmd /var/spool/slurmctld /var/log/slurm
cat > /etc/slurm/slurm.conf <<EOF
ClusterName=tstattest
SlurmctldHost=$HOST
AuthType=auth/munge
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
MpiDefault=none
ReturnToService=2
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
NodeName=$HOST CPUs=$CPUS RealMemory=$MEM_MB State=UNKNOWN
PartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
pkill -x slurmctld 2>/dev/null || true
pkill -x slurmd 2>/dev/null || true
sleep 1
slurmctld -c   # a clean state: no jobs left from an earlier run
slurmd
for _ in $(seq 60); do
  sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' && break
  sleep 1
done
scontrol update nodename="$HOST" state=resume 2>/dev/null || true
sinfo

# --- the job on Slurm ----------------------------------------------------------------
rm -rf "$WORK"
mkdir -p "$WORK"
DIR=$WORK/cluster
OPTS=(-- --spp 64 --width 64 --bins 100 --bin-width-opl 0.08 --seed 11)
"$TSTAT" cluster slurm "$ROOT/scenes/cbox.xml" --shards 4 --out "$DIR" --cpus 1 \
  --mem 1G --merge-mem 1G --time 00:20:00 --denoise "${OPTS[@]}"
cd /   # submit from another folder: the recipes name everything absolutely
RENDER_ID=$(sbatch --parsable "$DIR/render.sbatch")
MERGE_ID=$(sbatch --parsable --dependency=afterok:"$RENDER_ID" "$DIR/merge.sbatch")
echo "submitted render array $RENDER_ID, merge $MERGE_ID"
for _ in $(seq 600); do
  squeue -h -j "$RENDER_ID,$MERGE_ID" 2>/dev/null | grep -q . || break
  sleep 1
done
squeue -h -j "$RENDER_ID,$MERGE_ID" 2>/dev/null | grep -q . && { echo "FAIL: jobs still queued"; exit 1; }
cat "$DIR"/logs/*.log
[ -f "$DIR/merged.tstats/manifest.json" ] || { echo "FAIL: no merged bundle"; exit 1; }
[ -f "$DIR/denoised.npy" ] || { echo "FAIL: no denoised volume"; exit 1; }

# --- the same shards locally -----------------------------------------------------------
LOCAL=$WORK/local
mkdir -p "$LOCAL"
for i in 0 1 2 3; do
  "$TSTAT" render "$ROOT/scenes/cbox.xml" --shard "$i/4" --out "$LOCAL/s$i.tstats" \
    --threads 2 "${OPTS[@]:1}" 2>/dev/null
done
"$TSTAT" merge "$LOCAL"/s3.tstats "$LOCAL"/s1.tstats "$LOCAL"/s0.tstats "$LOCAL"/s2.tstats \
  --out "$LOCAL/merged.tstats"
"$TSTAT" denoise "$LOCAL/merged.tstats" --out "$LOCAL/denoised.npy" 2>/dev/null

status=0
for f in "$DIR"/merged.tstats/*.npy; do
  name=$(basename "$f")
  if cmp -s "$f" "$LOCAL/merged.tstats/$name"; then
    echo "identical: merged.tstats/$name"
  else
    echo "DIFFERENT: merged.tstats/$name"; status=1
  fi
done
if cmp -s "$DIR/denoised.npy" "$LOCAL/denoised.npy"; then
  echo "identical: denoised.npy"
else
  echo "DIFFERENT: denoised.npy"; status=1
fi
python3 - "$DIR/merged.tstats/manifest.json" "$LOCAL/merged.tstats/manifest.json" <<'EOF'
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
for m in (a, b):
    for k in ("render_seconds",):
        m.pop(k)
    m["scene"].pop("path")
assert a == b, "manifests differ beyond times"
print("manifests equal (render times aside): spp", a["spp"], "shards", a["shard"]["indices"], "job", a["shard"]["job"])
EOF
[ $status = 0 ] && echo PASS || { echo FAIL; exit 1; }
