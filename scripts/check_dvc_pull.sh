#!/usr/bin/env bash
# Push this clone's DVC outputs to the default remote, then check that a second clone
# beside it pulls them and has nothing left to reproduce (`dvc status` clean).
#
# The second clone gets what a commit of this run would carry (dvc.lock, the git-tracked
# metrics/reports, DVC's .gitignore files: every changed or new file git does not ignore),
# so the check does not need a commit. It is made beside this clone because the default
# remote's url is relative (.dvc/config: ../../rigmap-dvc-remote), and removed afterwards.
set -euo pipefail
cd "$(dirname "$0")/.."
clone=$PWD
dvc() { PATH="$clone/.venv/bin:$PATH" "$clone/.venv/bin/dvc" "$@"; }

remote=$(dvc remote list | awk '$NF == "(default)" {print $2}')
[ -n "$remote" ] || { echo "check_dvc_pull: no default DVC remote in .dvc/config" >&2; exit 1; }
started=$(date +%s)
dvc push --quiet
echo "check_dvc_pull: pushed to $remote in $(( $(date +%s) - started )) s"

second=$(mktemp -d "$clone/../rigmap-pull-check.XXXXXX")
trap 'rm -rf "$second"' EXIT
git clone --quiet "$clone" "$second"
# changed and new files (not ignored): exactly what committing this run would add
git status --porcelain --untracked-files=all | while read -r state path; do
    [ "$state" = "D" ] && { rm -f "$second/$path"; continue; }
    mkdir -p "$second/$(dirname "$path")"
    cp -p "$path" "$second/$path"
done

cd "$second"
started=$(date +%s)
dvc pull --quiet
echo "check_dvc_pull: a second clone pulled every output in $(( $(date +%s) - started )) s"
status=$(dvc status)
echo "$status"
grep -q "up to date" <<<"$status" || {
    echo "check_dvc_pull: the pulled clone still has stages to reproduce" >&2
    exit 1
}
