#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# The manual page xlate5(1) renders with man -l without a troff warning, and documents every
# option and command that --help lists, for the program and each of its commands.
# Usage: man_page.sh XLATE5 PAGE
set -euo pipefail
xlate5=$1 page=$2
fail() { echo "FAIL: $*" >&2; exit 1; }

[ -s "$page" ] || fail "$page missing or empty"
rendered=$(mktemp) warnings=$(mktemp)
trap 'rm -f "$rendered" "$warnings"' EXIT
LC_ALL=C.UTF-8 MANWIDTH=100 MAN_KEEP_FORMATTING= man --warnings -l "$page" >"$rendered" 2>"$warnings" || fail "man -l exited $?"
if [ -s "$warnings" ]; then cat "$warnings" >&2; fail "man -l printed warnings"; fi
for section in NAME SYNOPSIS DESCRIPTION OPTIONS COMMANDS "EXIT STATUS" ENVIRONMENT FILES EXAMPLES; do
  grep -q "^$section" "$rendered" || fail "no $section section"
done
# man renders the option hyphens as U+2212 MINUS or '-' depending on the locale: compare in ASCII.
text=$(sed 's/\xe2\x88\x92/-/g; s/\xe2\x80\x90/-/g' "$rendered" | col -b)

# Every command path: the program, its commands, and theirs (from the "Subcommands:" lists).
commands=("")
for ((i = 0; i < ${#commands[@]}; i++)); do
  read -r -a path <<<"${commands[i]}"
  help=$("$xlate5" "${path[@]}" --help)
  while read -r sub; do
    [ -n "$sub" ] && commands+=("${commands[i]:+${commands[i]} }$sub")
  done < <(sed -n '/^Subcommands:/,/^$/p' <<<"$help" | sed -n 's/^  \([a-z][-a-z]*\) .*/\1/p')
  [ -z "${commands[i]}" ] || grep -qF "xlate5 ${commands[i]}" <<<"$text" || fail "command 'xlate5 ${commands[i]}' not in the manual page"
  for option in $(sed -n '/^Options:/,/^$/p' <<<"$help" | grep -oE '^  (-[A-Za-z],)?--[A-Za-z][-A-Za-z0-9]*' | grep -oE -- '--[-A-Za-z0-9]+'); do
    case $option in --help|--version) continue ;; esac
    grep -qE -- "(^|[ ,])$option([ ,]|\$)" <<<"$text" || fail "option $option of 'xlate5 ${commands[i]}' not in the manual page"
  done
done
echo "manual page: ${#commands[@]} command levels checked against --help"
