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

# require_known SCRIPT [--flag FLAG] ONLY EXTRA AGENT_ROW...: exits with status 2 and a message
# listing the valid names unless every comma-separated name in ONLY (the value of FLAG, by default
# --agents) is the name of one of the AGENT_ROWs (NAME|...) or one of the space-separated EXTRA names.
require_known() {
    local script="$1" flag="--agents"
    shift
    if [[ "$1" == --flag ]]; then flag="$2"; shift 2; fi
    local only="$1" known=" $2 " v name
    shift 2
    for v in "$@"; do known+="${v%%|*} "; done
    for name in ${only//,/ }; do
        if [[ "$known" != *" $name "* ]]; then
            echo "$script: $flag: unknown agent \`$name\`; expected some of:$known" >&2
            exit 2
        fi
    done
}

# resume_on_interrupt SCRIPT: on Ctrl-C or TERM, says how to resume and exits with status 130.
resume_on_interrupt() {
    # shellcheck disable=SC2064  # the script's name is fixed now
    trap "echo; echo \"$1: interrupted — run the same command again to resume.\" >&2; exit 130" INT TERM
}

# agents_of GROUP ARRAY: fills ARRAY with the agents of experiments/agents.txt in GROUP (main,
# search, ablation), in the file's order, each as NAME|PRESET|TOML|WHAT; exits with status 2,
# naming the file and the group, when it has none.
agents_of() {
    local group="$1" line file
    local -n rows="$2"
    file="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/experiments/agents.txt"
    if [[ ! -f "$file" ]]; then
        echo "$file: not found (the agents of the experiments)" >&2
        exit 2
    fi
    rows=()
    while IFS= read -r line || [[ -n "$line" ]]; do
        [[ -z "$line" || "$line" == \#* ]] && continue
        if [[ "${line%%|*}" == "$group" ]]; then rows+=("${line#*|}"); fi
    done <"$file"
    if [[ ${#rows[@]} -eq 0 ]]; then
        echo "$file: no agent in group \`$group\`" >&2
        exit 2
    fi
}
