#!/usr/bin/env bash
# ctest driver for the live server's access control (issue 18): run.sh KINEMESH WORKDIR.
# tests/live/run.sh builds the character, starts `kinemesh live` on loopback with the rig
# file at mode 0600 and runs security.mjs against it (raw HTTP over loopback: forged Host,
# Origin, missing token, wrong content type, oversized body, WebSocket upgrades).
HERE=$(cd "$(dirname "$0")" && pwd)
export KM_LIVE_SCRIPT=$HERE/security.mjs KM_BIN=$1
exec bash "$HERE/../live/run.sh" security "$1" "$2"
