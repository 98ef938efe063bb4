#!/usr/bin/env bash
# A one-node SLURM cluster on this machine, for trying and testing profiles/slurm:
#
#   sudo scripts/local-slurm.sh install   # Debian/Ubuntu packages: slurm-wlm, slurmdbd, munge, mariadb-server
#   sudo scripts/local-slurm.sh start     # munge, MariaDB, slurmdbd, slurmctld, slurmd (loopback only)
#   snakemake results/report.html --profile profiles/slurm --configfile config/smoke.yaml
#   sudo scripts/local-slurm.sh stop      # stops every daemon and deletes the state folder
#
# Runs as root (SlurmUser=root), keeps its state in $NEURENDER_SLURM_DIR (default
# /tmp/neurender-slurm) and listens on loopback ports 16817-16819 and 13306 only.
# Accounting runs (slurmdbd + MariaDB) because the Snakemake SLURM executor asks sacct
# for job states. Job steps' own srun reads /etc/slurm/slurm.conf, so start links it there
# (an existing file is kept aside as slurm.conf.neurender-backup and restored by stop).
set -euo pipefail

STATE=${NEURENDER_SLURM_DIR:-/tmp/neurender-slurm}
CLUSTER=neurender
CTLD_PORT=16817
SLURMD_PORT=16818
DBD_PORT=16819
DB_PORT=13306
DB_PASSWORD=neurender-local

log() { echo "local-slurm: $*"; }

wait_for() {  # wait_for SECONDS DESCRIPTION COMMAND...
  local seconds=$1 what=$2
  shift 2
  for _ in $(seq "$((seconds * 5))"); do
    if "$@" >/dev/null 2>&1; then return 0; fi
    sleep 0.2
  done
  log "gave up waiting for $what after ${seconds}s (logs in $STATE/log)"
  tail -n 20 "$STATE"/log/*.log 2>/dev/null || true
  exit 1
}

install() {
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq slurm-wlm slurmdbd munge mariadb-server >/dev/null
  log "installed slurm-wlm, slurmdbd, munge, mariadb-server"
}

write_configs() {
  local cpus memory
  cpus=$(nproc)
  memory=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 1024 ))
  mkdir -p "$STATE"/{log,spool,state,mysql,run}
  cat >"$STATE/slurm.conf" <<EOF
ClusterName=$CLUSTER
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
AuthType=auth/munge
StateSaveLocation=$STATE/state
SlurmdSpoolDir=$STATE/spool
SlurmctldPidFile=$STATE/run/slurmctld.pid
SlurmdPidFile=$STATE/run/slurmd.pid
SlurmctldLogFile=$STATE/log/slurmctld.log
SlurmdLogFile=$STATE/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
MpiDefault=none
ReturnToService=2
MinJobAge=600
JobAcctGatherType=jobacct_gather/linux
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=localhost
AccountingStoragePort=$DBD_PORT
NodeName=localhost CPUs=$cpus RealMemory=$memory State=UNKNOWN
PartitionName=main Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
  cat >"$STATE/slurmdbd.conf" <<EOF
AuthType=auth/munge
DbdHost=localhost
DbdPort=$DBD_PORT
SlurmUser=root
PidFile=$STATE/run/slurmdbd.pid
LogFile=$STATE/log/slurmdbd.log
StorageType=accounting_storage/mysql
StorageHost=127.0.0.1
StoragePort=$DB_PORT
StorageUser=slurm
StoragePass=$DB_PASSWORD
StorageLoc=slurm_acct_db
EOF
  chmod 600 "$STATE/slurmdbd.conf"
}

start() {
  write_configs
  export SLURM_CONF=$STATE/slurm.conf
  # srun inside a job does not see SLURM_CONF: point the system config at ours.
  mkdir -p /etc/slurm
  if [ -e /etc/slurm/slurm.conf ] && [ ! -L /etc/slurm/slurm.conf ]; then
    mv /etc/slurm/slurm.conf /etc/slurm/slurm.conf.neurender-backup
  fi
  ln -sfn "$STATE/slurm.conf" /etc/slurm/slurm.conf

  mkdir -p /run/munge
  [ -f /etc/munge/munge.key ] || mungekey --create >/dev/null
  pgrep -x munged >/dev/null || munged --force
  wait_for 10 munge munge -n

  if [ ! -d "$STATE/mysql/mysql" ]; then
    mariadb-install-db --user=root --datadir="$STATE/mysql" --auth-root-authentication-method=normal >"$STATE/log/mariadb-install.log" 2>&1
  fi
  mariadbd --user=root --datadir="$STATE/mysql" --bind-address=127.0.0.1 --port=$DB_PORT \
    --socket="$STATE/run/mysql.sock" --pid-file="$STATE/run/mysql.pid" \
    --log-error="$STATE/log/mariadb.log" &
  wait_for 30 MariaDB mariadb --socket="$STATE/run/mysql.sock" -u root -e "SELECT 1"
  mariadb --socket="$STATE/run/mysql.sock" -u root <<EOF
CREATE USER IF NOT EXISTS 'slurm'@'localhost' IDENTIFIED BY '$DB_PASSWORD';
CREATE USER IF NOT EXISTS 'slurm'@'127.0.0.1' IDENTIFIED BY '$DB_PASSWORD';
CREATE DATABASE IF NOT EXISTS slurm_acct_db;
GRANT ALL ON slurm_acct_db.* TO 'slurm'@'localhost';
GRANT ALL ON slurm_acct_db.* TO 'slurm'@'127.0.0.1';
EOF

  slurmdbd
  wait_for 30 slurmdbd sacctmgr -n list cluster
  sacctmgr -i add cluster "$CLUSTER" >/dev/null 2>&1 || true
  sacctmgr -i add account root cluster="$CLUSTER" >/dev/null 2>&1 || true
  slurmctld
  slurmd
  wait_for 60 "the node to come up" sh -c "sinfo -h -o %T | grep -qE '^(idle|mixed|allocated)'"
  log "cluster $CLUSTER is up: SLURM_CONF=$SLURM_CONF (also /etc/slurm/slurm.conf)"
  sinfo
}

stop() {
  export SLURM_CONF=$STATE/slurm.conf
  local pids=() pid
  for pidfile in slurmd slurmctld slurmdbd mysql; do
    if [ -f "$STATE/run/$pidfile.pid" ]; then
      pid=$(cat "$STATE/run/$pidfile.pid")
      kill "$pid" 2>/dev/null && pids+=("$pid")
    fi
  done
  # slurmctld writes its state files as it shuts down: wait for every daemon to exit
  # (30 s, then SIGKILL) before the folder is removed, or rm races those writes.
  for _ in $(seq 30); do
    alive=0
    for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
    [ "$alive" -eq 0 ] && break
    sleep 1
  done
  for pid in "${pids[@]}"; do kill -9 "$pid" 2>/dev/null || true; done
  pkill -x munged 2>/dev/null || true
  if [ -L /etc/slurm/slurm.conf ]; then
    rm -f /etc/slurm/slurm.conf
    if [ -e /etc/slurm/slurm.conf.neurender-backup ]; then
      mv /etc/slurm/slurm.conf.neurender-backup /etc/slurm/slurm.conf
    fi
  fi
  rm -rf "$STATE"
  log "stopped and removed $STATE"
}

case "${1:-}" in
  install) install ;;
  start) start ;;
  stop) stop ;;
  *) echo "usage: $0 install|start|stop" >&2; exit 2 ;;
esac
