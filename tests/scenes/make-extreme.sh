# make-extreme.sh: turns make_box scenes (make-box.sh, sourced first) into the stiff and
# extreme cases of tests/stage/extreme.sh (docs/extreme-cases.md).
#
#   scale_scene DIR S
#       Scales the scene by S: mesh scale, camera eye and look_at, light positions, and the
#       point lights' intensities by S^2, so that every irradiance I cos / r^2, and so every
#       pixel, stays as it was (needs jq).
#   add_oddities DIR
#       Adds to make_box's cube (point lights only): a triangle with a repeated vertex and a
#       collinear one (zero area: the loader drops them), slivers 0.5 to 1 m long and 1e-6 m
#       wide, 1e-9 m wide (below float spacing at 0.2 m: zero area once in float) and 1e-7 m
#       wide, the last an emitter of Ke 1e6 (pi Ke A = 0.16 W per channel), and a second
#       floor, exactly coincident with the first, of another material with the same albedo.
#   add_cube_around_camera DIR
#       Adds a closed box 0.2 x 0.2 x 0.16 m around make_box's camera (0, 0, 0.9), clear of the room's
#       walls (a face on a wall would let the gather reach across it): zero-thickness
#       walls that reflect on both sides, nothing lit inside.
#   make_tiny_light DIR KE SIDE
#       A make_box cube of albedo 0.5 whose only light is a square emitter SIDE m across of
#       Ke KE W/(m^2 sr) at the centre, facing +z; the camera at (0, 0, 0.9) looks straight at
#       it through the centre of a 15 x 15 image, so the centre pixel sees the emitter.
scale_scene() {
    local dir=$1 s=$2
    jq --argjson s "$s" '.meshes[].scale = (.meshes[].scale // 1) * $s
        | .camera.eye |= map(. * $s) | .camera.look_at |= map(. * $s)
        | .point_lights |= map(.position |= map(. * $s) | .intensity |= map(. * $s * $s))' \
        "$dir/scene.json" >"$dir/scene.tmp" && mv "$dir/scene.tmp" "$dir/scene.json"
}

add_oddities() {
    local dir=$1
    cat >>"$dir/box.obj" <<'OBJ'
v 0.2 -0.5 0.1
v 0.7 -0.5 0.1
v 0.45 -0.5 0.1
v 0.2 -0.5 0.100001
v 0.2 -0.3 -0.5
v 0.2 0.7 -0.5
v 0.200000001 0.7 -0.5
v -0.6 -0.3 0.2
v -0.6 0.7 0.2
v -0.6 0.7 0.2000001
g oddities
usemtl wall
f 9 9 10
f 9 10 11
f 9 10 12
f 13 14 15
usemtl glow
f 16 17 18
g floor2
usemtl wall2
f 1 5 6 2
OBJ
    printf 'newmtl wall2\nKd 0.5 0.5 0.5\nnewmtl glow\nKd 0.5 0.5 0.5\nKe 1e6 1e6 1e6\n' >>"$dir/box.mtl"
}

add_cube_around_camera() {
    local dir=$1
    cat >>"$dir/box.obj" <<'OBJ'
v -0.1 -0.1 0.8
v 0.1 -0.1 0.8
v 0.1 0.1 0.8
v -0.1 0.1 0.8
v -0.1 -0.1 0.96
v 0.1 -0.1 0.96
v 0.1 0.1 0.96
v -0.1 0.1 0.96
g cell
usemtl wall
f 9 13 14 10
f 12 11 15 16
f 9 10 11 12
f 13 16 15 14
f 9 12 16 13
f 10 14 15 11
OBJ
}

make_tiny_light() {
    local dir=$1 ke=$2 side=$3
    make_box "$dir" 0.5 '[]'
    local h
    h=$(awk -v s="$side" 'BEGIN { printf "%.9g", s / 2 }')
    cat >>"$dir/box.obj" <<OBJ
v -$h -$h 0
v $h -$h 0
v $h $h 0
v -$h $h 0
g lamp
usemtl lamp
f 9 10 11 12
OBJ
    sed -i "s/^Ke 1 1 1$/Ke $ke $ke $ke/" "$dir/box.mtl"
    sed -i 's/"width": 16, "height": 16/"width": 15, "height": 15/' "$dir/scene.json"
}
