#!/usr/bin/env bash
# ctest driver: a Stroma server (Cyclone DDS, loopback) and the Fast DDS tool client together.
# Usage: run_fastdds_interop.sh STROMA_BINARY CLIENT_BINARY SCENARIO DOMAIN
set -euo pipefail
stroma="$1"; client="$2"; scenario="$3"; domain="$4"
"$stroma" serve "$scenario" --domain "$domain" --realtime off --duration 30 > /dev/null 2>&1 &
srv=$!
trap 'kill $srv 2>/dev/null || true' EXIT
sleep 0.5
"$client" "$domain" 3
kill -TERM $srv
wait $srv
