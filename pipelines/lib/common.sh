# pipelines/lib/common.sh: the scaffolding the shell drivers share (sourced by pipelines/frames,
# pipelines/slurm, pipelines/error-vs-time, pipelines/demo and pipelines/lib/slurm-task;
# pipelines/lib/slurm-preview is sourced by pipelines/slurm and runs with it), so that each says
# a failure, checks a number, reads NAME=VALUE parameters and prints its usage one way. The
# driver sets PM_NAME (the word its messages start with) first.
#
# Exit statuses are the programs' classes (docs/cli.md, "Exit status and errors"): 1 bad input,
# 2 usage, 3 the system failed (a retry may succeed), 4 a bug. A driver that runs stages passes
# their class through (pm_stage_status), so that its own caller can retry a full disk and not
# bad data.
PM_NAME=${PM_NAME:-${0##*/}}

# pm_die MESSAGE [STATUS]: "PM_NAME: MESSAGE" on stderr, then exit STATUS (default 1, bad input).
pm_die() {
    echo "$PM_NAME: $1" >&2
    exit "${2:-1}"
}

# pm_stage_status STATUS...: the exit class of a step made of stages that exited with these
# statuses (one, or a pipe's PIPESTATUS): 0 when all are 0; else 4 when one hit a bug, 3 when
# one failed for the system (the stages after it then fail on the short stream it left, and a
# stage before it on the broken pipe), else 1. A usage error (2) of a stage the driver started
# is the driver's command line, not the user's: 1, as any failure that is not the system's.
pm_stage_status() {
    local s worst=0
    for s in "$@"; do
        case "$s" in
        0) ;;
        4) worst=4 ;;
        3) [ $worst = 4 ] || worst=3 ;;
        *) [ $worst != 0 ] || worst=1 ;;
        esac
    done
    return $worst
}

# pm_stage_die MESSAGE STATUS...: pm_die MESSAGE with the class of the stages' statuses
# (pm_stage_status); e.g. `a | b || pm_stage_die "a or b failed" "${PIPESTATUS[@]}"`.
pm_stage_die() {
    local msg=$1
    shift
    pm_stage_status "$@"
    local c=$?
    [ $c != 0 ] || c=1 # called on a failure: never exit 0
    pm_die "$msg" $c
}

# pm_isnum WORD: a number of at least 0 as the stages' options read one (12, 1.5, .5, 5e5).
pm_isnum() { [[ $1 =~ ^[0-9]+([.][0-9]*)?([eE][-+]?[0-9]+)?$ || $1 =~ ^[.][0-9]+([eE][-+]?[0-9]+)?$ ]]; }

# pm_isint WORD [MIN]: a decimal integer of at least MIN (default 0); leading zeros are decimal.
pm_isint() { [[ $1 =~ ^[0-9]+$ ]] && ((10#$1 >= ${2:-0})); }

# pm_params TABLE GIVEN [OTHER] -- ARG...: reads NAME=VALUE arguments into the associative
# array TABLE, whose keys are the names allowed (its values the defaults); each name given is
# also a key of the associative array GIVEN. A name not in TABLE goes to the function OTHER
# when one is named (it returns 0 when it takes NAME=VALUE); otherwise, or when OTHER refuses
# it, it is a usage error (2) listing the names known (after PM_PARAMS_ALSO, the words for what
# OTHER takes, when set). A word that is not NAME=VALUE is a usage error too.
pm_params() {
    local -n pm_p_table=$1 pm_p_given=$2
    local other=$3 a n
    shift 4
    for a in "$@"; do
        case "$a" in
        *=*) ;;
        *) pm_die "unexpected argument '$a': parameters are NAME=VALUE" 2 ;;
        esac
        n=${a%%=*}
        if [ -n "$n" ] && [ -n "${pm_p_table[$n]+set}" ]; then
            pm_p_table[$n]=${a#*=}
            pm_p_given[$n]=1
        elif [ -z "$other" ] || ! "$other" "$n" "${a#*=}"; then
            pm_die "unknown parameter '$n' (known: ${PM_PARAMS_ALSO:+$PM_PARAMS_ALSO and }$(printf '%s\n' "${!pm_p_table[@]}" | sort | tr '\n' ' '))" 2
        fi
    done
}

# pm_usage START [END]: the driver's own manual, from the comment line that starts with
# "# START" to (without) the one that starts with "# END", or to the end of that comment
# block; each line without its "# ". A driver's --help is the manual it carries in its source.
pm_usage() {
    awk -v s="# $1" -v e="# ${2:-}" '
        !on && index($0, s) == 1 { on = 1 }
        on && (!/^#/ || (e != "# " && index($0, e) == 1)) { exit }
        on { sub(/^# ?/, ""); print }' "$0"
}
