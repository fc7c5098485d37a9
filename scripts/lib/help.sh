# Sourced by the scripts whose header comment is their whole usage: with -h or
# --help as the first argument, prints that comment (the lines after the #!
# line up to the first line that is not a comment) and exits 0.
#   source "$(dirname "${BASH_SOURCE[0]}")/lib/help.sh" "$@"
if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
  awk 'NR == 1 { next } /^#/ { sub(/^# ?/, ""); print; next } { exit }' "$0"
  exit 0
fi
