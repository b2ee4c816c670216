#!/usr/bin/env bash
# `cmake --install` into a scratch DESTDIR twice: the first install creates fieldgate.yaml and
# fieldgate.yaml.example; a site's edit to fieldgate.yaml survives the second, even when the
# build's copy is newer. Usage: install_keeps_config.sh BUILD_DIR
set -euo pipefail
build=$1
root=$(mktemp -d)
trap 'rm -rf "$root"' EXIT
DESTDIR="$root" cmake --install "$build" >/dev/null
config=$(find "$root" -name fieldgate.yaml -path '*/etc/fieldgate/*')
[ -n "$config" ] || { echo "FAIL: no fieldgate.yaml installed"; exit 1; }
[ -f "$config.example" ] || { echo "FAIL: no fieldgate.yaml.example installed"; exit 1; }
echo "ok: first install created ${config#"$root"} and its .example"
echo "# edited on site" >>"$config"
edited=$(sha256sum <"$config")
touch -d '2000-01-01' "$config"       # the site's file is older than the build's copy
touch "$build/fieldgate.yaml"
DESTDIR="$root" cmake --install "$build" >/dev/null
[ "$(sha256sum <"$config")" = "$edited" ] || { echo "FAIL: the edited config was overwritten"; exit 1; }
cmp -s "$build/fieldgate.yaml" "$config.example" || { echo "FAIL: .example not refreshed"; exit 1; }
echo "ok: the edited config survived a second install; the example was refreshed"
