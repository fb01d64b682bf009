# make-analytic.sh: writes scenes with closed-form answers (sourced by stage tests).
#
#   make_lit_plane DIR H I KD [HALF]
#       A square diffuse floor y = 0 of half-width HALF m (default 20) and grey albedo KD, lit by
#       an isotropic point light of intensity I W/sr (power Phi = 4 pi I per channel) at
#       (0, H, 0). Irradiance at a floor point at distance x from the foot of the light:
#           E(x) = I H / (H^2 + x^2)^(3/2) = Phi H / (4 pi (H^2 + x^2)^(3/2))
#       Light reflected by the floor escapes (there is nothing else), so this is also the total.
#       The camera sits at the light and looks straight down (fov 90: x, z in [-H, H]).
#
#   make_lit_sphere DIR R I KD [NSEG]
#       A closed UV sphere of radius R m (NSEG longitudes, NSEG/2 latitude bands, default 48),
#       grey Lambertian albedo KD, point light of intensity I W/sr at its centre, camera at the
#       centre looking along +z (fov 60). On a true sphere every area element sees the same
#       fraction dA / (4 pi R^2) of any diffuse reflection, so
#           direct irradiance  E_d = Phi / (4 pi R^2) = I / R^2
#           total irradiance   E   = E_d / (1 - KD)     (the bounce series sum KD^d)
#       The triangulated sphere is inscribed: a facet's points lie at distance R cos(a) for
#       a <= pi/NSEG or so, so its irradiance differs by about 1.5 (pi/NSEG)^2 (0.6% at 48).
#
# Lambertian radiance leaving a surface of irradiance E is L = KD / pi * E.
make_lit_plane() {
    local dir=$1 h=$2 i=$3 kd=$4 half=${5:-20}
    mkdir -p "$dir"
    cat >"$dir/plane.obj" <<OBJ
mtllib plane.mtl
v -$half 0 -$half
v $half 0 -$half
v $half 0 $half
v -$half 0 $half
usemtl floor
f 1 4 3 2
OBJ
    printf 'newmtl floor\nKd %s %s %s\n' "$kd" "$kd" "$kd" >"$dir/plane.mtl"
    cat >"$dir/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "lit-plane",
  "meshes": [ { "file": "plane.obj" } ],
  "camera": { "eye": [0, $h, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 90, "width": 32, "height": 32 },
  "point_lights": [ { "position": [0, $h, 0], "intensity": [$i, $i, $i] } ],
  "render": { "photons": 200000, "spp": 4, "seed": 1 }
}
JSON
}

make_lit_sphere() {
    local dir=$1 r=$2 i=$3 kd=$4 nseg=${5:-48}
    mkdir -p "$dir"
    awk -v r="$r" -v ns="$nseg" 'BEGIN {
        pi = 3.141592653589793; nr = int(ns / 2)
        print "mtllib sphere.mtl"
        print "v 0 " r " 0"                       # 1: north pole
        for (j = 1; j < nr; j++) {                # rings 1 .. nr-1
            t = pi * j / nr
            for (k = 0; k < ns; k++) {
                p = 2 * pi * k / ns
                printf "v %.17g %.17g %.17g\n", r * sin(t) * cos(p), r * cos(t), r * sin(t) * sin(p)
            }
        }
        south = 2 + (nr - 1) * ns
        print "v 0 " (-r) " 0"
        print "usemtl wall"
        for (k = 0; k < ns; k++) {
            k1 = (k + 1) % ns
            printf "f 1 %d %d\n", 2 + k1, 2 + k
            for (j = 1; j < nr - 1; j++) {
                a = 2 + (j - 1) * ns; b = a + ns
                printf "f %d %d %d %d\n", a + k, a + k1, b + k1, b + k
            }
            a = 2 + (nr - 2) * ns
            printf "f %d %d %d\n", south, a + k, a + k1
        }
    }' >"$dir/sphere.obj"
    printf 'newmtl wall\nKd %s %s %s\n' "$kd" "$kd" "$kd" >"$dir/sphere.mtl"
    cat >"$dir/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "lit-sphere",
  "meshes": [ { "file": "sphere.obj" } ],
  "camera": { "eye": [0, 0, 0], "look_at": [0, 0, 1], "fov_y": 60, "width": 32, "height": 32 },
  "point_lights": [ { "position": [0, 0, 0], "intensity": [$i, $i, $i] } ],
  "render": { "photons": 200000, "spp": 4, "seed": 1 }
}
JSON
}
