#!/usr/bin/env bash
# ctest driver (issue 18 §2; docs/CRTK.md): `stroma serve --crtk` (Cyclone DDS, loopback) and two
# CRTK clients on Fast DDS, as ROS 2 nodes would be on the wire: one drives the probe into the
# liver and reads measured_cf / measured_cp through the operating states, the other sends what
# must be refused. The server's --stats must count exactly the refusals.
# Usage: run_fastdds_crtk.sh STROMA_BINARY CLIENT_BINARY SCENARIO DOMAIN
set -euo pipefail
stroma="$1"; client="$2"; scenario="$3"; domain="$4"
tmp=$(mktemp -d)
"$stroma" serve "$scenario" --crtk --domain "$domain" --realtime off --duration 60 --stats "$tmp/stats.json" \
  > "$tmp/serve.log" 2>&1 &
srv=$!
trap 'kill $srv 2>/dev/null || true; rm -rf "$tmp"' EXIT
sleep 0.5
"$client" "$domain" drive probe
"$client" "$domain" malformed probe
kill -INT $srv
wait $srv
python3 - "$tmp/stats.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))["crtk"]
s = c["servo_cp"]
print("server counted:", json.dumps(c))
assert s["refused_invalid_stamp"] == 5, s
assert s["refused_non_finite"] == 5, s
assert s["refused_not_enabled"] == 1, s
assert s["refused_limits"] == 1, s           # the pose outside the workspace: FAULT
assert s["accepted"] >= 500, s               # ~2,000 sent at 1 kHz; fewer on a loaded machine
assert c["state_command"]["refused"] == 2, c
assert c["state_command"]["accepted"] == 4, c   # enable, pause, resume, enable (out of FAULT)
assert c["operating_state"]["probe"] == "ENABLED", c
# Every pose received is counted once (docs/CRTK.md), and the commands port agrees.
parts = sum(s[k] for k in ("accepted", "superseded", "refused_invalid_stamp", "refused_non_finite",
                           "refused_not_unit_quaternion", "refused_not_enabled", "refused_limits"))
assert parts == s["received"], s
assert json.load(open(sys.argv[1]))["tool_commands"]["received"] == s["received"], s
print("crtk counters ok")
PY
