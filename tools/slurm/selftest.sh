#!/usr/bin/env bash
# Runs the Slurm test (tests/slurm.rs) on a private single-host cluster:
# starts munged, slurmctld and slurmd (tools/slurm/cluster.sh, state in
# target/slurm), runs `cargo test --test slurm`, and stops the daemons again
# on exit, unless the cluster was already running before.
#
#   tools/slurm/selftest.sh [CARGO TEST ARGS...]     (default: -- --nocapture)
#
# Needs root and Debian's slurm-wlm and munge:
#   apt-get install -y slurm-wlm munge
set -euo pipefail
cd "$(dirname "$0")/../.."

cluster=tools/slurm/cluster.sh
if bash "$cluster" status >/dev/null 2>&1; then
    echo "selftest: using the cluster that is already running (left running)" >&2
else
    trap 'bash "$cluster" stop' EXIT
fi
bash "$cluster" start >/dev/null
SLURM_CONF=$(bash "$cluster" env | sed 's/^export SLURM_CONF=//')
export SLURM_CONF

# CI=true: the test fails instead of skipping when no cluster answers.
[ $# -gt 0 ] || set -- -- --nocapture
CI=true cargo test --test slurm "$@"
