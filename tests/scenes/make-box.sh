# make-box.sh: writes closed test scenes with known answers (sourced by stage tests).
#
#   make_box DIR ALBEDO LIGHTS [EXTRA_MTL]
#
# A closed cube [-1, 1]^3 m whose six walls face inward (right-hand rule) and share one
# grey Lambertian material of albedo ALBEDO. LIGHTS is the JSON array of point lights;
# with LIGHTS = "area" the cube has no point light and instead a 0.5 x 0.5 m emitter
# (Ke 1 1 1, Kd 0) just below the ceiling, facing down. EXTRA_MTL, when given, replaces
# the wall material's lines (e.g. "Kd 0.3 0.3 0.3\nKs 0.5 0.5 0.5\nNs 20" for a glossy box).
# Every photon emitted in it lands on a wall at its first hit, so first hits carry exactly
# the lights' power, and with albedo rho the photons at bounce d carry rho^d of it.
make_box() {
    local dir=$1 albedo=$2 lights=$3 extra=${4:-}
    mkdir -p "$dir"
    {
        echo "mtllib box.mtl"
        echo "v -1 -1 -1"; echo "v 1 -1 -1"; echo "v 1 1 -1"; echo "v -1 1 -1"
        echo "v -1 -1 1"; echo "v 1 -1 1"; echo "v 1 1 1"; echo "v -1 1 1"
        echo "g walls"; echo "usemtl wall"
        echo "f 1 5 6 2"  # floor, +y
        echo "f 4 3 7 8"  # ceiling, -y
        echo "f 1 2 3 4"  # z = -1, +z
        echo "f 5 8 7 6"  # z = +1, -z
        echo "f 1 4 8 5"  # x = -1, +x
        echo "f 2 6 7 3"  # x = +1, -x
        if [ "$lights" = area ]; then
            echo "v -0.25 0.98 -0.25"; echo "v 0.25 0.98 -0.25"; echo "v 0.25 0.98 0.25"; echo "v -0.25 0.98 0.25"
            echo "g lamp"; echo "usemtl lamp"
            echo "f 9 10 11 12"  # faces -y, into the room
        fi
    } >"$dir/box.obj"
    {
        echo "newmtl wall"
        if [ -n "$extra" ]; then printf '%b\n' "$extra"; else echo "Kd $albedo $albedo $albedo"; fi
        echo "newmtl lamp"
        echo "Kd 0 0 0"
        echo "Ke 1 1 1"
    } >"$dir/box.mtl"
    local pl=$lights
    [ "$lights" = area ] && pl="[]"
    cat >"$dir/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "box",
  "meshes": [ { "file": "box.obj" } ],
  "camera": { "eye": [0, 0, 0.9], "look_at": [0, 0, 0], "fov_y": 90, "width": 16, "height": 16 },
  "point_lights": $pl,
  "render": { "photons": 20000 }
}
JSON
}
