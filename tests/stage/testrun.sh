# testrun.sh: the test tiers themselves. Every stage script says which programs it runs on a
# `# programs:` line, every program is named by one, and tests/run selects scripts by program
# name (`tests/run trace-photons` runs the scripts that run it); `make check` names scripts
# that exist.
# programs: none
missing=""
for t in tests/stage/*.sh; do
    grep -qE '^# programs: [a-z]' "$t" || missing="$missing $(basename "$t")"
done
if [ -z "$missing" ]; then pass "every stage script has a '# programs:' line"; else fail "scripts without '# programs:'" "$missing"; fi
unnamed=""
for p in "$BIN"/*; do
    n=$(basename "$p")
    grep -qE "^# programs: (.* )?$n( |\$)" tests/stage/*.sh || unnamed="$unnamed $n"
done
if [ -z "$unnamed" ]; then pass "every program is named on some script's '# programs:' line"; else fail "programs no script names" "$unnamed"; fi
list=$(STAGE_SCRIPTS= bash tests/run --list trace-photons)
if echo "$list" | grep -qx tests/stage/photons.sh && echo "$list" | grep -qx tests/stage/analytic.sh &&
    ! echo "$list" | grep -qx tests/stage/compare.sh; then
    pass "tests/run trace-photons selects the scripts that run trace-photons, not the others"
else
    fail "tests/run --list trace-photons" "$(echo "$list" | tr '\n' ' ')"
fi
if [ -z "$(STAGE_SCRIPTS= bash tests/run --list kdtree_build)" ]; then pass "a unit test's name selects no stage script"; else fail "tests/run --list kdtree_build" "$(STAGE_SCRIPTS= bash tests/run --list kdtree_build | tr '\n' ' ')"; fi
if [ "$(STAGE_SCRIPTS="pmtk formats" bash tests/run --list | tr '\n' ' ')" = "tests/stage/formats.sh tests/stage/pmtk.sh " ]; then
    pass "STAGE_SCRIPTS narrows tests/run to those scripts"
else
    fail "STAGE_SCRIPTS" "$(STAGE_SCRIPTS="pmtk formats" bash tests/run --list | tr '\n' ' ')"
fi
checks=$(sed -n 's/^CHECK_SCRIPTS := //p' Makefile)
bad=""
for c in $checks; do [ -f "tests/stage/$c.sh" ] || bad="$bad $c"; done
if [ -n "$checks" ] && [ -z "$bad" ]; then pass "make check's scripts exist: $checks"; else fail "CHECK_SCRIPTS" "missing:$bad"; fi
