# huge-malloc.sh: pm-render re-executes itself with glibc's malloc on huge pages
# (GLIBC_TUNABLES glibc.malloc.hugetlb=1; docs/cli.md, "Huge pages for malloc"), and every
# program it starts inherits it:
#   1. a pass hook, started with the stages' environment, sees glibc.malloc.hugetlb=1 and
#      glibc.malloc.top_pad=67108864 (the heap grown 64 MiB at a time) added to GLIBC_TUNABLES
#      after the tunables it had, the top_pad only when those do not name one, and not
#      PMTK_START_S (the first start's time, which only the re-executed driver reads);
#   2. a GLIBC_TUNABLES that names glibc.malloc.hugetlb is left as it is, and PMTK_HUGE_MALLOC=0
#      re-executes nothing;
#   3. the image is the same bytes either way, and trace-reference's the same pixels.
# Where glibc is older than 2.35 or transparent huge pages are off, nothing is re-executed, and
# checks 1 and 2 expect that.
# programs: pm-render trace-reference
H=$TMP/huge
mkdir -p "$H"
CB=scenes/cornell-box/scene.json
cat >"$H/hook.sh" <<'SH'
#!/bin/sh
echo "tunables=${GLIBC_TUNABLES-unset} start=${PMTK_START_S-unset}" >>"$HOOK_OUT"
SH
chmod +x "$H/hook.sh"

# whether this machine's glibc and kernel let malloc use huge pages
v=$(getconf GNU_LIBC_VERSION 2>/dev/null | awk '{ split($2, a, "."); print a[1] * 1000 + a[2] }')
huge=0
if [ "${v:-0}" -ge 2035 ] && [ -r /sys/kernel/mm/transparent_hugepage/enabled ] &&
    ! grep -q '\[never\]' /sys/kernel/mm/transparent_hugepage/enabled; then
    huge=1
fi

# hook_env NAME [VAR=VALUE...]: render the Cornell box (2 passes, 24 x 16) into $H/NAME with
# GLIBC_TUNABLES and PMTK_HUGE_MALLOC unset but for the VARs given, the hook's lines into
# $H/NAME.hook
hook_env() {
    local name=$1
    shift
    rm -rf "$H/$name" "$H/$name.hook"
    env -u GLIBC_TUNABLES -u PMTK_HUGE_MALLOC "$@" HOOK_OUT="$H/$name.hook" RENDER_PASS_HOOK="$H/hook.sh" \
        "$BIN/pm-render" "$CB" "$H/$name" WIDTH=24 HEIGHT=16 PASSES=2 PHOTONS=2000 -q >"$TMP/out" 2>"$TMP/err"
}

# expect_hook NAME WANT: every line the hook wrote for render NAME is WANT, and it wrote two
expect_hook() {
    local got n
    n=$(grep -c . "$H/$1.hook" 2>/dev/null)
    got=$(sort -u "$H/$1.hook" 2>/dev/null)
    if [ "$n" = 2 ] && [ "$got" = "$2" ]; then pass "$1: $2"; else fail "$1" "hook saw '$got' ($n lines), expected '$2' twice: $(head -c 300 "$TMP/err")"; fi
}

hook_env plain
if [ $huge = 1 ]; then
    expect_hook plain "tunables=glibc.malloc.hugetlb=1:glibc.malloc.top_pad=67108864 start=unset"
else
    expect_hook plain "tunables=unset start=unset"
fi
hook_env other GLIBC_TUNABLES=glibc.malloc.arena_max=2
if [ $huge = 1 ]; then
    expect_hook other "tunables=glibc.malloc.arena_max=2:glibc.malloc.hugetlb=1:glibc.malloc.top_pad=67108864 start=unset"
else
    expect_hook other "tunables=glibc.malloc.arena_max=2 start=unset"
fi
hook_env pad GLIBC_TUNABLES=glibc.malloc.top_pad=1048576
if [ $huge = 1 ]; then
    expect_hook pad "tunables=glibc.malloc.top_pad=1048576:glibc.malloc.hugetlb=1 start=unset"
else
    expect_hook pad "tunables=glibc.malloc.top_pad=1048576 start=unset"
fi
hook_env user GLIBC_TUNABLES=glibc.malloc.hugetlb=0
expect_hook user "tunables=glibc.malloc.hugetlb=0 start=unset"
hook_env off PMTK_HUGE_MALLOC=0
expect_hook off "tunables=unset start=unset"
expect_same "the image is the same bytes with malloc on huge pages and without" "$H/plain/image.exr" "$H/off/image.exr"

for m in on off; do
    env -u GLIBC_TUNABLES -u PMTK_HUGE_MALLOC $([ $m = off ] && echo PMTK_HUGE_MALLOC=0) "$BIN/trace-reference" -q "$CB" --width 16 \
        --height 12 --spp 8 --pass 8 -o "$H/ref-$m.exr" 2>"$TMP/err" || fail "trace-reference ($m)" "$(head -c 300 "$TMP/err")"
done
# (its EXR's header holds the run's time: the pixels are compared)
if "$BIN/measure-error" "$H/ref-on.exr" "$H/ref-off.exr" 2>"$TMP/err" | grep -qE '"rmse": 0(\.0)?,'; then
    pass "trace-reference's pixels are the same with malloc on huge pages and without"
else
    fail "trace-reference's pixels are the same with malloc on huge pages and without" "$(head -c 300 "$TMP/err")"
fi
