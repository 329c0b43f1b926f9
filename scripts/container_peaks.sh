#!/usr/bin/env bash
# Sample the memory, CPU and process count of a compose project's containers, and print each
# service's peaks: what services/deploy/compose.py's LIMITS are set from (docs/deploy.md).
#
#   scripts/container_peaks.sh sample PROJECT FILE   append `docker stats --no-stream` samples of
#                                                    PROJECT's containers to FILE until stopped
#                                                    (SIGTERM/SIGINT); one sample every ≈ 2 s
#   scripts/container_peaks.sh peaks FILE            each service's peak memory (MiB), CPU (% of
#                                                    one CPU) and PIDs (processes and threads)
#
# e.g. scripts/container_peaks.sh sample rocosmoke /var/tmp/peaks.tsv & bash scripts/compose_smoke.sh;
#      kill %1; scripts/container_peaks.sh peaks /var/tmp/peaks.tsv
# A sample line: UNIX-TIME NAME MEM-USAGE CPU-PERCENT PIDS (tab-separated, as docker stats
# prints them: "123.4MiB / 23.4GiB", "87.21%").
set -euo pipefail

usage() { sed -n '2,14p' "$0" >&2; exit 2; }

case "${1:-}" in
    sample)
        [ $# -eq 3 ] || usage
        project=$2 file=$3
        trap 'exit 0' TERM INT
        while :; do
            now=$(date +%s)
            docker stats --no-stream --format '{{.Name}}\t{{.MemUsage}}\t{{.CPUPerc}}\t{{.PIDs}}' 2>/dev/null |
                awk -v p="$project" -v t="$now" 'index($1, p "_") == 1 || index($1, p "-") == 1 { print t "\t" $0 }' \
                    >>"$file" || true
            sleep 1
        done
        ;;
    peaks)
        [ $# -eq 2 ] || usage
        [ -s "$2" ] || { echo "container_peaks.sh: no samples in $2" >&2; exit 1; }
        # a container's name is PROJECT_SERVICE_N (compose 1.29) or PROJECT-SERVICE-N (v2)
        awk -F'\t' '
            function mib(s,    n, u) {
                n = s + 0; u = s; sub(/^[0-9.]+/, "", u)
                if (u == "KiB") return n / 1024; if (u == "GiB") return n * 1024
                if (u == "B") return n / 1048576; return n
            }
            {
                name = $2; sub(/^[^_-]+[_-]/, "", name); sub(/[_-][0-9]+$/, "", name)
                split($3, used, " / "); m = mib(used[1]); c = $4 + 0; p = $5 + 0
                if (m > mem[name]) mem[name] = m
                if (c > cpu[name]) cpu[name] = c
                if (p > pids[name]) pids[name] = p
                n[name]++
            }
            END {
                printf "%-10s %9s %8s %6s %8s\n", "service", "mem MiB", "CPU %", "PIDs", "samples"
                for (s in mem) printf "%-10s %9.0f %8.1f %6d %8d\n", s, mem[s], cpu[s], pids[s], n[s]
            }' "$2" | { read -r head; echo "$head"; sort; }
        ;;
    *) usage ;;
esac
