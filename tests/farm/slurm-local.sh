#!/usr/bin/env bash
# A copy of the project's shared single-node Slurm recipe (shared/farm/slurm-local.sh), kept in the
# repository so that tests/farm_slurm.rs runs from a clone alone. Its own description follows.
# Single-node Slurm (Debian bookworm slurm-wlm 22.05) for CI, no systemd.
#
#   slurm-local-test.sh [test]   install if needed, start munged+slurmctld+slurmd, run a 4-task job array
#                                + an afterok "assemble" job, verify outputs, stop everything (default)
#   slurm-local-test.sh up       install if needed and start; leaves daemons running, prints SLURM_CONF
#   slurm-local-test.sh down     stop the daemons a previous `up` started (by their pid files only)
#
# Env knobs: SLURM_CI_DIR (default: slurm-ci in the temp dir), SLURM_CI_AUTH=munge|none (default munge),
#            SLURM_CI_CTLD_PORT (6817), SLURM_CI_D_PORT (6818), SLURM_CI_TIMEOUT (job wait, s; 120),
#            SLURM_CI_EXTRA_CONF (extra slurm.conf lines appended verbatim),
#            SLURM_CI_FAIL_SHARD=<i> (make array task i exit 3, to check failure detection; script then exits 1).
# Must run as root (apt-get, munge user switch, slurmd launching jobs). Idempotent: re-running
# first stops daemons left by an earlier run of this script (pid files in $SLURM_CI_DIR), then
# recreates $SLURM_CI_DIR from scratch. Only processes this script started are ever signalled.
set -euo pipefail

MODE=${1:-test}
D=${SLURM_CI_DIR:-${TMPDIR:-$(dirname "$(mktemp -u)")}/slurm-ci}
AUTH=${SLURM_CI_AUTH:-munge}
CTLD_PORT=${SLURM_CI_CTLD_PORT:-6817}
D_PORT=${SLURM_CI_D_PORT:-6818}
TIMEOUT=${SLURM_CI_TIMEOUT:-120}
export SLURM_CONF=$D/slurm.conf
T0=$(date +%s%N)

log() { local ms=$(( ($(date +%s%N) - T0) / 1000000 )); printf '[slurm-ci %3d.%03ds] %s\n' $((ms/1000)) $((ms%1000)) "$*"; }
die() { log "FAIL: $*"; exit 1; }

# --- stop helpers: only PIDs recorded in our own pid files, and only if the name matches ---
stop_pidfile() {  # $1 = pid file, $2 = expected process name
  local f=$1 name=$2 pid
  [ -s "$f" ] || return 0
  pid=$(cat "$f")
  if [ "$(cat "/proc/$pid/comm" 2>/dev/null || true)" = "$name" ]; then   # no procps needed
    kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq 200); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    if kill -0 "$pid" 2>/dev/null; then log "$name ($pid) ignored SIGTERM, sending SIGKILL"; kill -KILL "$pid" || true; fi
    log "stopped $name (pid $pid)"
  fi
  rm -f "$f"
}

down() {
  stop_pidfile "$D/pids/slurmd" slurmd
  stop_pidfile "$D/pids/slurmctld" slurmctld
  stop_pidfile "$D/pids/munged" munged      # only present if WE started munged
}

install_pkgs() {
  if command -v slurmctld >/dev/null && command -v slurmd >/dev/null && command -v sbatch >/dev/null \
     && command -v munged >/dev/null; then
    log "slurm already installed: $(slurmctld -V)"
    return
  fi
  log "installing slurm-wlm + munge (no recommends)"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null
  log "installed $(slurmctld -V), $(munged --version 2>&1 | head -1)"
}

start_munge() {
  # Reuse a munged that already answers (not ours -> we never stop it); else start our own.
  if munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
    log "munged already running (not started by us) - reusing"
    return
  fi
  [ -s /etc/munge/munge.key ] || { log "creating munge key"; mungekey --create --force >/dev/null 2>&1 || \
      dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none; }
  chown munge:munge /etc/munge/munge.key; chmod 0400 /etc/munge/munge.key
  mkdir -p /run/munge && chown munge:munge /run/munge && chmod 0755 /run/munge   # systemd RuntimeDirectory=
  rm -f /run/munge/munged.pid
  runuser -u munge -- /usr/sbin/munged          # daemonizes; writes /run/munge/munged.pid
  for _ in $(seq 50); do [ -s /run/munge/munged.pid ] && break; sleep 0.1; done
  cp /run/munge/munged.pid "$D/pids/munged"
  munge -n | unmunge >/dev/null || die "munge round-trip failed (see /var/log/munge/munged.log)"
  log "munged started (pid $(cat "$D/pids/munged"))"
}

write_conf() {
  local authline="AuthType=auth/munge
CredType=cred/munge"
  [ "$AUTH" = none ] && authline="AuthType=auth/none
CredType=cred/none"
  cat > "$SLURM_CONF" <<EOF
ClusterName=ci
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
$authline
SlurmctldPort=$CTLD_PORT
SlurmdPort=$D_PORT
StateSaveLocation=$D/state
SlurmdSpoolDir=$D/spool
SlurmctldPidFile=$D/run/slurmctld.pid
SlurmdPidFile=$D/run/slurmd.pid
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$D/log/jobcomp.txt
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
SchedulerParameters=batch_sched_delay=0
DependencyParameters=kill_invalid_depend
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
SlurmdTimeout=30
InactiveLimit=0
NodeName=localhost CPUs=$(nproc) RealMemory=$(( $(awk '/^MemTotal:/{print $2}' /proc/meminfo) / 1024 * 9 / 10 )) State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
${SLURM_CI_EXTRA_CONF:-}
EOF
}

up() {
  [ "$(id -u)" = 0 ] || die "must run as root"
  down                                   # leftovers from an earlier run of this script
  install_pkgs
  rm -rf "$D"; mkdir -p "$D"/{state,spool,log,run,pids,work}
  for p in "$CTLD_PORT" "$D_PORT"; do
    if (exec 3<>/dev/tcp/127.0.0.1/"$p") 2>/dev/null; then die "port $p already in use (another Slurm?); set SLURM_CI_CTLD_PORT/SLURM_CI_D_PORT"; fi
  done
  [ "$AUTH" = none ] || start_munge
  write_conf
  # -D = stay in foreground (we background them ourselves); logs go to stderr.
  slurmctld -D -f "$SLURM_CONF" >"$D/log/slurmctld.log" 2>&1 &  echo $! > "$D/pids/slurmctld"
  slurmd -D -N localhost -f "$SLURM_CONF" >"$D/log/slurmd.log" 2>&1 &  echo $! > "$D/pids/slurmd"
  log "slurmctld pid $(cat "$D/pids/slurmctld"), slurmd pid $(cat "$D/pids/slurmd") (auth=$AUTH)"
  local st=""
  for _ in $(seq 300); do
    st=$(sinfo -h -n localhost -o %T 2>/dev/null || true)
    [ "$st" = idle ] && break
    kill -0 "$(cat "$D/pids/slurmctld")" 2>/dev/null || { tail -20 "$D/log/slurmctld.log"; die "slurmctld died"; }
    kill -0 "$(cat "$D/pids/slurmd")" 2>/dev/null || { tail -20 "$D/log/slurmd.log"; die "slurmd died"; }
    sleep 0.1
  done
  [ "$st" = idle ] || { tail -20 "$D/log/slurmctld.log" "$D/log/slurmd.log"; die "node not idle after 30 s (state '$st')"; }
  log "cluster up: $(sinfo -h -o '%P %a %D %T %N')"
}

wait_jobs() {  # $@ = job ids; polls squeue (faster than sbatch --wait's 2/8/32 s back-off)
  local ids; ids=$(IFS=,; echo "$*")
  local end=$(( $(date +%s) + TIMEOUT ))
  while squeue -h -j "$ids" 2>/dev/null | grep -q .; do
    [ "$(date +%s)" -lt "$end" ] || { squeue; die "jobs $ids not done after ${TIMEOUT}s"; }
    sleep 0.5
  done
}

demo() {
  local W=$D/work N=4
  cd "$W"
  # Shard step: one array task per shard; stands in for `render --shard $i/$n`.
  local A B
  A=$(sbatch --parsable --array=0-$((N-1)) -J render -o "$W/render-%A_%a.log" \
        --wrap 'echo "shard $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT host=$(hostname) job=$SLURM_ARRAY_JOB_ID" > shard-$SLURM_ARRAY_TASK_ID.txt
                [ "$SLURM_ARRAY_TASK_ID" != "${SLURM_CI_FAIL_SHARD:-none}" ] || exit 3')
  # Assemble step: runs only if ALL array tasks exit 0.
  B=$(sbatch --parsable --dependency=afterok:"$A" -J assemble -o "$W/assemble.log" \
        --wrap "cat $(for i in $(seq 0 $((N-1))); do printf 'shard-%s.txt ' "$i"; done) > assembled.txt")
  log "submitted array job $A (tasks 0-$((N-1))) and assemble job $B (afterok:$A)"
  wait_jobs "$A" "$B"
  log "jobs finished"
  # Per-task final states (kept for MinJobAge=300 s). sacct is unavailable (no slurmdbd).
  local states; states=$(squeue -h -t all -j "$A,$B" -o '%i=%T' | sort | tr '\n' ' ')
  log "states: $states"
  [ "$(squeue -h -t all -j "$A,$B" -o '%T' | grep -vc '^COMPLETED$' || true)" = 0 ] || die "not all jobs COMPLETED"
  for i in $(seq 0 $((N-1))); do
    grep -qx "shard $i/$N host=$(hostname) job=$A" "shard-$i.txt" || die "shard-$i.txt wrong/missing"
  done
  [ "$(wc -l < assembled.txt)" = "$N" ] || die "assembled.txt has $(wc -l < assembled.txt) lines"
  log "all $N shard files + assembled.txt verified:"; sed 's/^/    /' assembled.txt
  log "jobcomp records: $(wc -l < "$D/log/jobcomp.txt") (ExitCode per task in $D/log/jobcomp.txt)"
}

case "$MODE" in
  up)   up; echo "export SLURM_CONF=$SLURM_CONF" ;;
  down) down ;;
  test) trap 'rc=$?; down; log "exit rc=$rc"; exit $rc' EXIT
        up; demo; log "OK" ;;
  *)    echo "usage: $0 [test|up|down]" >&2; exit 2 ;;
esac
