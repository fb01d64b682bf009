# transforms.sh: mesh placement (docs/scene-format.md, Transforms) through the stages: a plane
# turned by `rotate` and moved by `translate`, lit by a point light on its new normal, gives the
# closed-form irradiance E = I h / (h^2 + x^2)^(3/2) at every pixel's hit; the same placement
# written as one `matrix` renders the same pixels; bad transforms are refused in one line and
# nothing is written.
# programs: composite trace-gather-points
source tests/scenes/make-analytic.sh
PI=3.141592653589793

# The floor of make_lit_plane (y = 0, front +y) turned 30 degrees about +z and moved to
# (1, 2, 3): its normal becomes (-sin 30, cos 30, 0). Light and camera 1 m along that normal
# from (1, 2, 3), the camera looking back at it. place_plane DIR PLACEMENT-JSON.
place_plane() {
    local dir=$1 place=$2
    make_lit_plane "$dir" 1 $PI 0.5
    cat >"$dir/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "turned-plane",
  "meshes": [ { "file": "plane.obj", $place } ],
  "camera": { "eye": [0.5, 2.8660254037844386, 3], "look_at": [1, 2, 3], "up": [0, 0, 1], "fov_y": 90,
              "width": 32, "height": 32 },
  "point_lights": [ { "position": [0.5, 2.8660254037844386, 3], "intensity": [$PI, $PI, $PI] } ],
  "render": { "spp": 4, "seed": 1 }
}
JSON
}

# direct_image SCENE NAME: the gather-mode direct buffer (exact here: nothing lies in front of
# the plane, so next-event estimation of the point light is the whole image) as text in
# $TMP/NAME.txt, and the primary hits in $TMP/NAME.hits.txt.
direct_image() {
    "$BIN/trace-gather-points" "$1" --spp 4 -q -o "$TMP/$2.q.pm" --direct "$TMP/$2.d.pm" &&
        "$BIN/composite" "$TMP/$2.d.pm" -q -o "$TMP/$2.exr" &&
        "$BUILD/tests/pm-exrdump" "$TMP/$2.exr" >"$TMP/$2.txt" &&
        "$BIN/trace-gather-points" "$1" --mode direct-vis -q -o "$TMP/$2.hq.pm" &&
        "$BIN/pm-info" -r "$TMP/$2.hq.pm" >"$TMP/$2.hits.txt"
}

place_plane "$TMP/rot" '"rotate": { "axis": [0, 0, 1], "degrees": 30 }, "translate": [1, 2, 3]'
if direct_image "$TMP/rot/scene.json" rot; then
    # Every hit on the intended plane, with its normal: a turn the wrong way or about the wrong
    # point fails here even where the image would still match its own geometry.
    if awk '$1 ~ /^[0-9]+$/ && NF >= 11 {
            n++; d = -0.5 * ($2 - 1) + 0.8660254037844386 * ($3 - 2)
            c = -0.5 * $5 + 0.8660254037844386 * $6
            if (d > 1e-5 || d < -1e-5 || c < 0.99999) { bad++; if (!why) why = sprintf("hit %s %s %s normal %s %s %s", $2, $3, $4, $5, $6, $7) }
        }
        END { if (n != 1024 || bad) { printf "%d hits, %d off the plane: %s\n", n, bad, why; exit 1 } }' \
        "$TMP/rot.hits.txt" >"$TMP/why"; then
        pass "rotate + translate: 1024 hits on the plane through (1 2 3) of normal (-sin 30, cos 30, 0)"
    else
        fail "rotate + translate: hits on the intended plane" "$(cat "$TMP/why")"
    fi
    if awk -v kind=point -v kd=0.5 -v I=$PI -v lx=0.5 -v ly=2.8660254037844386 -v lz=3 \
        -v tmean=1e-5 -v trms=1e-5 -v tmax=1e-5 -f tests/scenes/analytic.awk "$TMP/rot.hits.txt" "$TMP/rot.txt" \
        >"$TMP/why"; then
        pass "rotated plane under a point light: L = kd/pi * I h / (h^2 + x^2)^(3/2) ($(cat "$TMP/why"))"
    else
        fail "rotated plane under a point light" "$(tr '\n' ' ' <"$TMP/why")"
    fi
else
    fail "rotated plane pipeline" "a stage failed"
fi

# The same placement as one row-major matrix (rotation by 30 degrees about z, then the move):
# the same pixels (the files' headers differ only in the scene's hash, which covers scene.json).
place_plane "$TMP/mat" '"matrix": [0.8660254037844387, -0.5, 0, 1,  0.5, 0.8660254037844387, 0, 2,  0, 0, 1, 3,  0, 0, 0, 1]'
if direct_image "$TMP/mat/scene.json" mat; then
    if cmp -s "$TMP/rot.txt" "$TMP/mat.txt"; then
        pass "matrix equal to rotate + translate: the same pixels"
    else
        fail "matrix equal to rotate + translate" "images differ: $(diff "$TMP/rot.txt" "$TMP/mat.txt" | head -3 | tr '\n' ' ')"
    fi
else
    fail "matrix plane pipeline" "a stage failed"
fi

# Bad transforms: one line naming the key and the value, exit 1, no output file.
bad_transform() {
    local name=$1 pattern=$2 place=$3
    place_plane "$TMP/bad" "$place"
    rm -f "$TMP/bad.q.pm"
    expect_error "$name" "$pattern" "$BIN/trace-gather-points" "$TMP/bad/scene.json" -q -o "$TMP/bad.q.pm"
    [ -e "$TMP/bad.q.pm" ] && fail "$name: nothing written" "$TMP/bad.q.pm exists"
}
bad_transform "singular matrix refused" "meshes\[0\]\.matrix: is singular" \
    '"matrix": [1, 0, 0, 0,  0, 0, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]'
bad_transform "projective matrix refused" "last row 0 0 1 1 is not 0 0 0 1" \
    '"matrix": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 1, 1]'
bad_transform "matrix of 12 numbers refused" "must be an array of 16 numbers .* not 12" \
    '"matrix": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0]'
bad_transform "NaN in a matrix refused" "line 4" \
    '"matrix": [NaN, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]'
bad_transform "zero rotation axis refused" "rotate\.axis: is the zero vector" \
    '"rotate": { "axis": [0, 0, 0], "degrees": 30 }'
