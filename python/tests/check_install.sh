#!/usr/bin/env bash
# check_install.sh BUILD_DIR PYTHON REL_DIR PREFIX: `cmake --install` into a
# temporary prefix puts the frictiond package under PREFIX/REL_DIR, and the
# interpreter imports it from there (outside the build tree); for the
# configured PREFIX (default /usr/local), PREFIX/REL_DIR is on the interpreter's own
# sys.path, so no PYTHONPATH is needed after a real install.
set -euo pipefail
build=$1 python=$2 rel=$3 prefix=${4:-/usr/local}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" >/dev/null
pkg=$work/prefix/$rel/frictiond
ls "$pkg"/_core*.so "$pkg"/__init__.py "$pkg"/_core.pyi "$pkg"/py.typed >/dev/null
cd "$work"
PYTHONPATH=$work/prefix/$rel "$python" -c "
import frictiond, sys
assert frictiond.__file__.startswith('$work/prefix/'), frictiond.__file__
m = frictiond.Model.from_json({'material': 'x'})
assert not m.has_stochastic
"
env -u PYTHONPATH "$python" -c "
import sys
want = '$prefix/$rel'
assert want in sys.path, (want, sys.path)
"
echo "check_install: frictiond installed under PREFIX/$rel and importable"
