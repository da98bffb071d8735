# Helpers shared by the scripts in this directory (sourced, not run).

# require_positive SCRIPT NAME:VALUE...: exits with status 2 and a message naming the flag unless
# every VALUE is a positive number.
require_positive() {
    local script="$1" pair name value
    shift
    for pair in "$@"; do
        name="${pair%%:*}" value="${pair#*:}"
        if ! [[ "$value" =~ ^[0-9]+([.][0-9]+)?$ ]] || [[ "$value" =~ ^0+([.]0+)?$ ]]; then
            echo "$script: --$name $value must be a positive number" >&2
            exit 2
        fi
    done
}
