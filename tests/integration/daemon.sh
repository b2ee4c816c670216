# Kept for the scripts outside tests/integration that source it (tests/vcan): the shared helpers
# are in lib.sh.
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
