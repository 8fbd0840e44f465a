#!/usr/bin/env bash
# ctest driver (issue 18 §2; docs/CRTK.md): `stroma serve --crtk` (Cyclone DDS, loopback) and two
# CRTK clients on Fast DDS, as ROS 2 nodes would be on the wire: one drives the probe into the
# liver and reads measured_cf / measured_cp through the operating states, the other sends what
# must be refused. The server's --stats must count exactly the refusals.
# With `secure`, the domain is protected (DDS Security: identities of `stroma security init`):
# the clients authenticate with a client identity, and a third Fast DDS client without one must
# reach nothing (SECURITY.md).
# Usage: run_fastdds_crtk.sh STROMA_BINARY CLIENT_BINARY SCENARIO DOMAIN [secure]
set -euo pipefail
stroma="$1"; client="$2"; scenario="$3"; domain="$4"; mode="${5:-open}"
tmp=$(mktemp -d)
security=()
if [ "$mode" = secure ]; then
  "$stroma" security init "$tmp/sec" --client tool=probe > /dev/null
  security=(--security "$tmp/sec")
fi
"$stroma" serve "$scenario" --crtk "${security[@]}" --domain "$domain" --realtime off --duration 90 \
  --stats "$tmp/stats.json" > "$tmp/serve.log" 2>&1 &
srv=$!
trap 'kill $srv 2>/dev/null || true; rm -rf "$tmp"' EXIT
sleep 0.5
if [ "$mode" = secure ]; then
  # An intruder: no identity. It must not even see the device's state.
  if "$client" "$domain" drive probe > "$tmp/intruder.log" 2>&1; then
    echo "FAIL: a Fast DDS client without an identity drove the protected server"; exit 1
  fi
  grep -q "no DISABLED state" "$tmp/intruder.log" && echo "intruder refused"
  export STROMA_FASTDDS_SECURITY="$tmp/sec:tool"
fi
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
