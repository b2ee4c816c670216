#!/usr/bin/env bash
# `fieldgate check --protocol` on every deliberately broken protocol file of broken/: each is
# refused (exit status not 0), at the file:line:column its second line names, with the text it
# names ("# expect: LINE:COLUMN: TEXT"). Every good shipped file passes the same command.
# Usage: check_broken_files.sh FIELDGATE PROTOCOLS_DIR
set -euo pipefail
fieldgate=$1 shipped=$2
here=$(cd "$(dirname "$0")" && pwd)
failed=0 checked=0
for file in "$here"/broken/*.yaml; do
  expect=$(sed -n '2s/^# expect: //p' "$file")
  where=${expect%%: *} says=${expect#*: }
  [ -n "$expect" ] || { echo "FAIL: $file has no '# expect:' line"; failed=1; continue; }
  rc=0
  out=$("$fieldgate" check --protocol "$file" 2>&1) || rc=$?
  checked=$((checked + 1))
  if [ "$rc" -eq 0 ]; then
    echo "FAIL: $(basename "$file"): accepted"; failed=1
  elif ! grep -qF -- "$file:$where: " <<<"$out"; then
    echo "FAIL: $(basename "$file"): not refused at $where:"; echo "$out"; failed=1
  elif ! grep -F -- "$file:$where: " <<<"$out" | grep -qF -- "$says"; then
    echo "FAIL: $(basename "$file"): refused at $where, but not with '$says':"; echo "$out"; failed=1
  else
    echo "ok: $(basename "$file") refused at $where ($says)"
  fi
done
[ "$checked" -ge 10 ] || { echo "FAIL: only $checked broken files"; failed=1; }
for file in "$shipped"/*.yaml; do
  "$fieldgate" check --protocol "$file" >/dev/null 2>&1 ||
    { echo "FAIL: shipped $(basename "$file") refused"; failed=1; }
done
exit "$failed"
