#!/bin/bash
# Checks scripts/slurm_study.sh on a one-node Slurm cluster started here from Debian's
# packages (slurmctld, slurmd, munge): a study run as a job array of 3 slices and merged
# must give the bytes of the same study run directly. Needs root; installs the packages if
# missing; stops the daemons it started. Not part of the test suite (it starts system
# daemons); its result is recorded in docs/reproducing.md.
#
#   scripts/check_slurm.sh [STUDY [subslam study flags]]     # default: fmj --trials 2
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
STUDY="${1:-fmj}"
shift || true
FLAGS=("$@")
((${#FLAGS[@]})) || FLAGS=(--trials 2)
SUBSLAM="$ROOT/build/apps/subslam"
[[ $(id -u) -eq 0 ]] || { echo "check_slurm: needs root (starts munged, slurmctld, slurmd)" >&2; exit 1; }
[[ -x "$SUBSLAM" ]] || { echo "check_slurm: build first (scripts/setup.sh)" >&2; exit 1; }
missing=()
for p in slurmctld slurmd slurm-client munge; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

WORK="$(mktemp -d /tmp/subslam_slurm.XXXXXX)"
HOST="$(hostname -s)"
CPUS="$(nproc)"
mkdir -p "$WORK"/{state,spool,log,munge}
cat > "$WORK/slurm.conf" <<CONF
ClusterName=subslam-check
SlurmctldHost=$HOST
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CryptoType=crypto/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
StateSaveLocation=$WORK/state
SlurmdSpoolDir=$WORK/spool
SlurmctldPidFile=$WORK/slurmctld.pid
SlurmdPidFile=$WORK/slurmd.pid
SlurmctldLogFile=$WORK/log/slurmctld.log
SlurmdLogFile=$WORK/log/slurmd.log
JobCompType=jobcomp/none
NodeName=$HOST CPUs=$CPUS State=UNKNOWN
PartitionName=check Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$WORK/slurm.conf"

# munge: a fresh key in the work directory, its own socket.
dd if=/dev/urandom of="$WORK/munge/munge.key" bs=1 count=1024 status=none
chmod 400 "$WORK/munge/munge.key"
MUNGE_SOCKET="$WORK/munge/munge.socket"
munged --force --key-file="$WORK/munge/munge.key" --socket="$MUNGE_SOCKET" \
  --pid-file="$WORK/munge/munged.pid" --log-file="$WORK/munge/munged.log" --seed-file="$WORK/munge/seed"
cleanup() {
  kill "$(cat "$WORK/slurmd.pid" 2>/dev/null)" "$(cat "$WORK/slurmctld.pid" 2>/dev/null)" 2>/dev/null || true
  kill "$(cat "$WORK/munge/munged.pid" 2>/dev/null)" 2>/dev/null || true
}
trap cleanup EXIT
# Slurm's munge plugin reads the socket from its AuthInfo.
sed -i "s|^AuthType=auth/munge|AuthType=auth/munge\nAuthInfo=socket=$MUNGE_SOCKET|" "$WORK/slurm.conf"
slurmctld -f "$WORK/slurm.conf"
slurmd -f "$WORK/slurm.conf"
for _ in $(seq 60); do
  sinfo -h -o "%T" 2>/dev/null | grep -qE "idle|mixed" && break
  sleep 1
done
sinfo

OUT="$WORK/out"
SUBSLAM="$SUBSLAM" "$ROOT/scripts/slurm_study.sh" "$STUDY" "$OUT" 3 "${FLAGS[@]}"
for _ in $(seq 1800); do
  [[ -z "$(squeue -h 2>/dev/null)" ]] && break
  sleep 1
done
[[ -f "$OUT/merged/summary.md" ]] || { echo "check_slurm: no merged summary; logs in $WORK" >&2; exit 1; }
"$SUBSLAM" study "$STUDY" "${FLAGS[@]}" --quiet --progress=false --out "$WORK/direct"
status=0
for f in config.json runs.csv summary.json summary.md $( [[ -f "$WORK/direct/series.csv" ]] && echo series.csv ); do
  if cmp -s "$OUT/merged/$f" "$WORK/direct/$f"; then echo "same: $f"; else echo "DIFFERENT: $f"; status=1; fi
done
echo "check_slurm: $([[ $status -eq 0 ]] && echo "the job array's merged study is the direct run's, byte for byte" || echo FAILED) ($WORK)"
exit $status
