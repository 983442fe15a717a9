#!/usr/bin/env bash
# Schema check of the Kubernetes Indexed Job manifest under hil-tests/campaigns/kubernetes: the
# PyPI `kubernetes-validate` package (strict: unknown fields are errors) against the schemas of
# Kubernetes 1.29 (the oldest with backoffLimitPerIndex on by default) and 1.37. A copy with a
# misspelt field must fail, so the check can fail. It does not run the Job (no cluster here).
# The venv lives in target/k8s-venv and is reused. Exits non-zero on any failure.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
venv="$root/target/k8s-venv"
python="${PYTHON:-python3}"
want="1.37.0"

if ! "$venv/bin/python" -c "import importlib.metadata as m; assert m.version('kubernetes-validate') == '$want'" 2>/dev/null; then
    echo "k8s-check: creating $venv with kubernetes-validate==$want"
    rm -rf "$venv"
    "$python" -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check "kubernetes-validate==$want"
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
for manifest in hil-tests/campaigns/kubernetes/*.yaml; do
    for version in 1.29.0 1.37.0; do
        "$venv/bin/kubernetes-validate" --strict -k "$version" "$manifest"
    done
    sed 's/^  completionMode: Indexed$/  completionMode: Indexed\n  completionMod: Indexed/' "$manifest" >"$work/bad.yaml"
    if "$venv/bin/kubernetes-validate" --strict --quiet -k 1.29.0 "$work/bad.yaml" >/dev/null 2>&1; then
        echo "k8s-check: a manifest with a misspelt field passed: the check cannot fail" >&2
        exit 1
    fi
done
echo "k8s-check: passed"
