#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# The bash completion completes options (also a command's own), commands and machine names
# from what the program itself lists.
# Usage: bash_completion.sh XLATE5 COMPLETION_SCRIPT
set -euo pipefail
xlate5=$1
# shellcheck source=/dev/null
source "$2"
fail() { echo "FAIL: $*" >&2; exit 1; }
# complete WORD... : the candidates for the last word, as bash would ask for them.
complete_words() {
  COMP_WORDS=("$xlate5" "$@")
  COMP_CWORD=$#
  COMP_LINE="${COMP_WORDS[*]}"
  COMP_POINT=${#COMP_LINE}
  COMPREPLY=()
  _xlate5
  printf '%s\n' "${COMPREPLY[@]}"
}
expect() {  # expect "WORDS" CANDIDATE...: each candidate is offered
  local words=$1; shift
  local got
  read -r -a argv <<<"$words"
  got=$(complete_words "${argv[@]}" "${EXTRA:-}")
  for want in "$@"; do
    grep -qxF -- "$want" <<<"$got" || fail "'xlate5 $words' offers [$(tr '\n' ' ' <<<"$got")], not '$want'"
  done
}
EXTRA=--tol expect "" --tolerance
EXTRA=ma expect "" machines
EXTRA=se expect "" serve
EXTRA=--p expect "serve" --printer --port --pty --pty-group
EXTRA=f expect "calibrate" fit
EXTRA=--or expect "calibrate fit" --order
EXTRA=rw expect "--machine" rw2
EXTRA=core expect "--from" core-rtheta
EXTRA=fi expect "" firmware-config
EXTRA=kl expect "firmware-config --firmware" klipper
EXTRA=G43 expect "--mode" G43.4 G43.5
# A command's options are not offered before it.
got=$(complete_words --pr)
grep -qx -- --printer <<<"$got" && fail "'xlate5 --pr' offers serve's --printer"
echo "bash completion: ok"
