#!/usr/bin/env bash
# Runs the smoke sequence in `wfsbench tui` inside tmux the way a person would: keys in with
# send-keys, the screen read back with capture-pane, each step waiting (with a deadline) for what
# the technician would wait for. Ends on the results screen, prints it, and quits the UI.
#
#   docs/tui_smoke_tmux.sh [CAMPAIGN_FILE]      (WFSBENCH=path/to/wfsbench to use another binary)
set -euo pipefail

wfsbench=${WFSBENCH:-wfsbench}
out=${1:-$(mktemp -d)/smoke.h5}
session=wfsbench-tui-$$

# a tmux server of its own (socket named as the session): another tmux on the machine and its
# options cannot change this one's 120 x 40 window
tmux() { command tmux -L "$session" -f /dev/null "$@"; }
# COLUMNS and LINES left in the environment (a test runner's worker sets 80 x 24) would override
# the size of the pane the UI runs in
tmux new-session -d -s "$session" -x 120 -y 40 "env -u COLUMNS -u LINES $wfsbench tui --out '$out'"
trap 'tmux kill-server 2>/dev/null || true' EXIT

# wait_for SECONDS PATTERN...: until the screen shows every PATTERN (fixed strings)
wait_for() {
    local seconds=$1
    shift
    local deadline=$((SECONDS + seconds))
    while :; do
        local screen missing=0
        screen=$(tmux capture-pane -p -t "$session" 2>/dev/null) || screen=""
        for pattern in "$@"; do
            grep -qF -- "$pattern" <<<"$screen" || missing=1
        done
        [ "$missing" = 0 ] && return 0
        if [ "$SECONDS" -ge "$deadline" ]; then
            echo "timed out after ${seconds} s waiting for: $*" >&2
            echo "$screen" >&2
            return 1
        fi
        sleep 0.2
    done
}

wait_for 60 "controller link up"                  # Bench screen: the simulated lab is open
tmux send-keys -t "$session" F3                     # Sequence screen
wait_for 10 "shipped sequences"
tmux send-keys -t "$session" Enter                  # smoke.toml, the first shipped sequence
wait_for 60 "g: start this sequence"
tmux send-keys -t "$session" g                      # start: the Run screen
wait_for 60 "Remove the wheel" "y: done"
tmux send-keys -t "$session" y
wait_for 60 "Fit the wheel" "y: done"
tmux send-keys -t "$session" y
wait_for 60 "pressure read on the gauge" "then Enter"
tmux send-keys -t "$session" 2.5 Enter              # the pressure read on the gauge
# the Results screen, once it shows the grid's analysis (it arrives after the runs are listed)
wait_for 120 "runs of the open file" "finished" "smoke-s010-sweep" "Model 2 selected" "valid band 2 mm compensated"
tmux capture-pane -p -t "$session"
# q quits once the sequence has ended (the last run's analysis may still be finishing: the UI then
# says so and q is pressed again); the UI closes the campaign file as it quits: wait for its
# session to end (at most 30 s)
for _ in $(seq 30); do
    tmux send-keys -t "$session" q 2>/dev/null || true
    for _ in $(seq 5); do
        tmux has-session -t "$session" 2>/dev/null || exit 0
        sleep 0.2
    done
done
echo "the UI did not quit within 30 s" >&2
exit 1
