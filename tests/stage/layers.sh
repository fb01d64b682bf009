# layers.sh: the library's include rules (docs/architecture.md, "Layers").
#
# Every include of a pmtk header names its layer ("base/error.h", "formats/formats.h"); a
# file may include only its own layer and the layers below it, so that dependencies point
# one way. A ../ path, a layer reached upwards, or an include of a header that does not
# exist fails here, with the file, the line and the rule it broke.
# programs: none

# layer: the layers its files may include (itself first).
layer_allows() {
    case $1 in
    base) echo "base" ;;
    math) echo "math base" ;;
    formats) echo "formats base" ;;
    physics) echo "physics math formats base" ;; # the BSDFs: below the tracers and the gathers
    render) echo "render physics math formats base" ;;
    photonmap) echo "photonmap physics math formats base" ;;
    image) echo "image math formats base" ;;
    engine) echo "engine render photonmap image physics math formats base" ;;
    api) echo "api engine render photonmap image physics math formats base" ;; # the public API: over everything
    top) echo "api engine render photonmap image physics math formats base" ;; # stages/, tests/: anything in the library
    esac
}

layer_of() {
    case $1 in
    common/base/*) echo base ;;
    common/math/*) echo math ;;
    formats/*) echo formats ;;
    common/physics/*) echo physics ;;
    common/render/*) echo render ;;
    common/photonmap/*) echo photonmap ;;
    common/image/*) echo image ;;
    common/engine/*) echo engine ;;
    common/api/*) echo api ;;
    common/*) echo stray ;; # a file directly in common/ belongs to no layer
    *) echo top ;;
    esac
}

# check_layers ROOT: prints one line per violation, nothing when the tree keeps the rules.
check_layers() (
    cd "$1" || exit 1
    git ls-files -co --exclude-standard -- 'common/*.[ch]' 'formats/*.[ch]' 'stages/*.[ch]' 'tests/*.[ch]' |
        while IFS= read -r f; do
            [ -f "$f" ] || continue
            l=$(layer_of "$f")
            if [ "$l" = stray ]; then
                echo "$f: not in a layer folder (common/base, math, physics, render, photonmap, image, engine, api)"
                continue
            fi
            allowed=$(layer_allows "$l")
            grep -n '^[[:space:]]*#[[:space:]]*include[[:space:]]*"' "$f" |
                sed -E 's/^([0-9]+):[^"]*"([^"]*)".*/\1 \2/' |
                while read -r n inc; do
                    case $inc in
                    ../* | */../*)
                        echo "$f:$n: include '$inc' climbs with ../; name the layer instead"
                        continue
                        ;;
                    */*) ;;
                    pmtk.h)
                        # The public header (include/pmtk.h): for the api layer and above.
                        case " $allowed " in
                        *" api "*) ;;
                        *) echo "$f:$n: layer $l includes the public pmtk.h, which only the api layer and above may" ;;
                        esac
                        continue
                        ;;
                    *)
                        # A bare name is a file beside the includer (tests' own unit.h).
                        [ -f "$(dirname "$f")/$inc" ] || echo "$f:$n: include '$inc' names no layer"
                        continue
                        ;;
                    esac
                    top=${inc%%/*}
                    case $top in
                    base | math | physics | render | photonmap | image | engine) path=common/$inc ;;
                    formats) path=$inc ;;
                    *)
                        echo "$f:$n: include '$inc' is not in a layer (base, math, formats, physics, render, photonmap, image, engine)"
                        continue
                        ;;
                    esac
                    [ -f "$path" ] || echo "$f:$n: include '$inc': no such header $path"
                    case " $allowed " in
                    *" $top "*) ;;
                    *) echo "$f:$n: layer $l includes '$inc' from layer $top, which is not below it (allowed: $allowed)" ;;
                    esac
                done
        done
)

out=$(check_layers .)
if [ -z "$out" ]; then
    pass "layers: every include names its layer and points down"
else
    fail "layers" "$(printf '%s\n' "$out" | head -n 20)"
fi

# The check itself must catch a wrong-way include, a ../ path, an include across from the
# image layer to render and the physics layer reaching up to the tracers: copy the tree's layout
# with four bad files and expect each named.
mkdir -p "$TMP/layers/common/base" "$TMP/layers/common/render" "$TMP/layers/common/image" "$TMP/layers/formats" \
    "$TMP/layers/common/physics"
(
    cd "$TMP/layers" && git init -q . &&
        printf '#include "render/x.h"\n' >common/base/bad.c &&
        printf '#include "../base/bad.h"\n' >common/render/x.h &&
        printf '#include "render/x.h"\n' >common/image/across.c &&
        printf '#include "render/x.h"\n' >common/physics/up.c &&
        printf '#include "formats/y.h"\n' >formats/y.h
)
bad=$(check_layers "$TMP/layers")
if echo "$bad" | grep -q "common/base/bad.c:1: layer base includes 'render/x.h'" &&
    echo "$bad" | grep -q "common/render/x.h:1: include '../base/bad.h' climbs" &&
    echo "$bad" | grep -q "common/image/across.c:1: layer image includes 'render/x.h'" &&
    echo "$bad" | grep -q "common/physics/up.c:1: layer physics includes 'render/x.h'" &&
    ! echo "$bad" | grep -q "formats/y.h"; then
    pass "layers: the check names an upward include, a ../ path, image reaching across to render and physics up to it"
else
    fail "layers: the check names an upward include, a ../ path and image reaching across" "got: $bad"
fi
