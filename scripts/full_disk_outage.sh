#!/bin/bash
# A worker's run under a full disk, as a user meets it: `inertia-id serve` on SQLite, its
# data dir on a small filesystem (MOUNT, e.g. `mount -t tmpfs -o size=40m tmpfs MOUNT`,
# as root) that is filled during a random search and freed HOLD_S seconds after the run
# ended. Prints the job's end (status, attempts, error) and the worker's log lines while
# the disk was full. Its logs go outside MOUNT (else they could not be written).
#
#   scripts/full_disk_outage.sh MOUNT [TIMESTEPS=8000] [HOLD_S=15] [PORT=18093]
set -u
MOUNT=${1:?a small mounted filesystem, emptied first}; STEPS=${2:-8000}; HOLD=${3:-15}
PORT=${4:-18093}
WORK=$(mktemp -d); LOGS=$WORK/logs; LOG=$WORK/worker.log; mkdir -p "$LOGS"
rm -rf "${MOUNT:?}"/*; mkdir -p "$MOUNT/data"; ln -s "$LOGS" "$MOUNT/data/logs"
export INERTIA_ID_API_KEY=full-disk-outage-0123456789abcdef
export INERTIA_ID_HEARTBEAT_INTERVAL_S=1 INERTIA_ID_HEARTBEAT_TIMEOUT_S=10
API=http://127.0.0.1:$PORT; H="X-API-Key: $INERTIA_ID_API_KEY"
field() { python -c "import sys,json;print(json.load(sys.stdin)[\"$1\"])" 2>/dev/null; }
status() { curl -s -H "$H" "$API/jobs/$1" | field status; }
collect() { cat "$LOGS"/worker*.log >"$LOG" 2>/dev/null; }
python -m inertia_id.cli serve --port "$PORT" --data-dir "$MOUNT/data" --workers 1 \
    >"$WORK/serve.log" 2>&1 &
SERVE=$!
stop() {
    kill $SERVE $(ss -ltnpH "sport = :$PORT" | grep -o "pid=[0-9]*" | cut -d= -f2 | sort -u) \
        2>/dev/null
    rm -f "$MOUNT/fill"
}
trap stop EXIT
for _ in $(seq 120); do curl -sf -H "$H" "$API/health" >/dev/null && break; sleep 1; done
SC=$(curl -s -H "$H" -XPOST "$API/scenarios" -H 'content-type: application/json' \
    -d '{"preset":"paper"}' | field id)
BODY="{\"type\":\"search\",\"scenario_id\":\"$SC\",\"seed\":1,\"params\":{\"method\":\"random\",
\"sequence_length\":2,\"timesteps\":$STEPS,\"n_realisations\":5,\"metric\":\"euclidean\",
\"sakoe_chiba_radius\":2,\"fuel_weight\":0.0,\"patience_episodes\":null}}"
JOB=$(curl -s -H "$H" -XPOST "$API/jobs" -H 'content-type: application/json' -d "$BODY" | field id)
[ -n "$JOB" ] || { echo "no job submitted"; exit 1; }
for _ in $(seq 200); do [ "$(status "$JOB")" = running ] && break; sleep 0.5; done
sleep 2; collect; START=$(wc -l <"$LOG")
dd if=/dev/zero of="$MOUNT/fill" bs=1M 2>/dev/null; echo "disk full at $(date +%T)"
for _ in $(seq 300); do
    collect
    grep -q "could not store its outcome\|job $JOB succeeded\|job $JOB failed" "$LOG" && break
    sleep 1
done
echo "run ended at $(date +%T)"; sleep "$HOLD"
collect; FREED=$(wc -l <"$LOG"); rm -f "$MOUNT/fill"; echo "disk freed at $(date +%T)"
for _ in $(seq 120); do
    case $(status "$JOB") in succeeded | failed | cancelled) break ;; esac; sleep 1
done
curl -s -H "$H" "$API/jobs/$JOB" | python -c 'import sys,json;j=json.load(sys.stdin);print("job",
j["status"],"attempts",j["attempts"],"error",j["error"])'
echo "worker log while full: $((FREED - START)) lines, $(sed -n "$START,${FREED}p" "$LOG" |
    grep -c '^Traceback') tracebacks"
sed -n "$START,${FREED}p" "$LOG" | grep '^\[' | cut -c1-240
