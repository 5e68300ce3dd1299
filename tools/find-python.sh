#!/usr/bin/env bash
# Prints the path of a Python X.Y interpreter (the one a Blender release's bpy wheel is built for):
# PATH first, then pyenv's versions, then Debian's package where the release has it.
set -eu
want=${1:?usage: find-python.sh X.Y}
ok() { [ -x "$1" ] && "$1" -c "import sys, venv; sys.exit(sys.version_info[:2] != tuple(map(int, '$want'.split('.'))))" 2>/dev/null; }
for cand in "$(command -v "python$want" 2>/dev/null || true)" \
            $(ls -d "${PYENV_ROOT:-$HOME/.pyenv}"/versions/"$want"*/bin/python"$want" 2>/dev/null | sort -V -r) \
            /usr/local/bin/python"$want" /usr/bin/python"$want"; do
  [ -n "$cand" ] && ok "$cand" && { echo "$cand"; exit 0; }
done
# Not found: try the distribution's package (python3.X-venv), then pyenv's installer.
sudo_cmd=""; [ "$(id -u)" = 0 ] || sudo_cmd="sudo"
if command -v apt-get >/dev/null && apt-cache show "python$want-venv" >/dev/null 2>&1; then
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq "python$want-venv" >&2 && ok "/usr/bin/python$want" && { echo "/usr/bin/python$want"; exit 0; }
fi
if command -v pyenv >/dev/null; then
  pyenv install -s "$want" >&2 && cand=$(ls -d "${PYENV_ROOT:-$HOME/.pyenv}"/versions/"$want"*/bin/python"$want" | sort -V -r | head -1) && ok "$cand" && { echo "$cand"; exit 0; }
fi
echo "find-python: no Python $want here (needed by this Blender version's bpy); install it, or set PY_SYS=/path/to/python$want" >&2
exit 1
