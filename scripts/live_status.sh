# shellcheck shell=bash
# live_status LABEL LOG CMD...: run CMD with its output (stdout and stderr) in LOG and return its
# exit status. On a terminal, a status line under the script's own lines shows LABEL, the
# seconds CMD has run and LOG's last line, redrawn once a second and erased when CMD ends; off
# a terminal (CI, a pipe) nothing is drawn. Sourced by scripts/build_image.sh.
live_status() {
    local label=$1 log=$2
    shift 2
    if [ ! -t 1 ]; then
        "$@" > "$log" 2>&1
        return
    fi
    "$@" > "$log" 2>&1 &
    local pid=$! t0 cols last
    t0=$(date +%s)
    cols=$(tput cols 2>/dev/null || echo 80)
    while kill -0 "$pid" 2>/dev/null; do
        last=$(tail -n 1 "$log" 2>/dev/null | tr -d '\r\033' | cut -c1-$((cols > 40 ? cols - 30 : 10)))
        printf '\r\033[K%s %4d s | %s' "$label" "$(($(date +%s) - t0))" "$last"
        sleep 1
    done
    printf '\r\033[K'
    wait "$pid"
}
