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
#   make_furnace DIR LE KD [R] [NSEG]
#       The furnace: the same UV sphere (radius R m, default 1) wound inward, so that the
#       right-hand-rule front face of every triangle, the side area lights emit from
#       (docs/scene-format.md), faces the centre; every surface emits LE W/(m^2 sr) (MTL Ke)
#       and reflects with grey albedo KD. No point lights; camera at the centre along +z
#       (fov 60). In a closed enclosure of uniform emission and albedo the radiance is the
#       same everywhere and in every direction, whatever the shape:
#           L = LE + KD L  =>  L = LE / (1 - KD)       irradiance E = pi L at every point
#       The triangulation therefore makes no bias here; only the kernel sees the facets' kinks.
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

# sphere_obj R NSEG WINDING: the UV sphere's OBJ on stdout (material "wall"), with every
# face's right-hand-rule normal pointing out (WINDING out) or in (WINDING in).
sphere_obj() {
    awk -v r="$1" -v ns="$2" -v inward=$([ "$3" = in ] && echo 1 || echo 0) '
    function face3(a, b, c) { if (inward) printf "f %d %d %d\n", a, c, b; else printf "f %d %d %d\n", a, b, c }
    function face4(a, b, c, d) {
        if (inward) printf "f %d %d %d %d\n", a, d, c, b; else printf "f %d %d %d %d\n", a, b, c, d
    }
    BEGIN {
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
            face3(1, 2 + k1, 2 + k)
            for (j = 1; j < nr - 1; j++) {
                a = 2 + (j - 1) * ns; b = a + ns
                face4(a + k, a + k1, b + k1, b + k)
            }
            a = 2 + (nr - 2) * ns
            face3(south, a + k, a + k1)
        }
    }'
}

make_lit_sphere() {
    local dir=$1 r=$2 i=$3 kd=$4 nseg=${5:-48}
    mkdir -p "$dir"
    sphere_obj "$r" "$nseg" out >"$dir/sphere.obj"
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

make_furnace() {
    local dir=$1 le=$2 kd=$3 r=${4:-1} nseg=${5:-48}
    mkdir -p "$dir"
    sphere_obj "$r" "$nseg" in >"$dir/sphere.obj"
    printf 'newmtl wall\nKd %s %s %s\nKe %s %s %s\n' "$kd" "$kd" "$kd" "$le" "$le" "$le" >"$dir/sphere.mtl"
    cat >"$dir/scene.json" <<JSON
{
  "pmtk_scene": 1,
  "name": "furnace",
  "meshes": [ { "file": "sphere.obj" } ],
  "camera": { "eye": [0, 0, 0], "look_at": [0, 0, 1], "fov_y": 60, "width": 32, "height": 32 },
  "render": { "photons": 200000, "spp": 4, "seed": 1 }
}
JSON
}

# obj_area FILE: the total area of an OBJ's faces, m^2 (polygons as triangle fans), on stdout.
# The inscribed UV sphere of 48 x 24 has 0.35% less area than the true one, so on average its
# irradiance is 0.35% higher (the same power on less area).
obj_area() {
    awk '$1 == "v" { n++; x[n] = $2; y[n] = $3; z[n] = $4 }
        $1 == "f" {
            split($2, a, "/"); i0 = a[1]
            for (k = 3; k < NF; k++) {
                split($k, b, "/"); split($(k + 1), c, "/"); i1 = b[1]; i2 = c[1]
                ux = x[i1] - x[i0]; uy = y[i1] - y[i0]; uz = z[i1] - z[i0]
                vx = x[i2] - x[i0]; vy = y[i2] - y[i0]; vz = z[i2] - z[i0]
                cx = uy * vz - uz * vy; cy = uz * vx - ux * vz; cz = ux * vy - uy * vx
                s += sqrt(cx * cx + cy * cy + cz * cz) / 2
            }
        }
        END { printf "%.17g\n", s }' "$1"
}

# The checks of the scripts that source this file (analytic.sh, guide.sh, specular-pipeline.sh),
# on files in $AN_DIR (default $TMP):
# image IMG BUFFER... [composite options]: composite into $AN_DIR/IMG.exr, read back as text into
# $AN_DIR/IMG.txt.
image() {
    local img=$1 d=${AN_DIR:-$TMP}; shift
    "$BIN/composite" "$@" -q -o "$d/$img.exr" && "$BUILD/tests/pm-exrdump" "$d/$img.exr" >"$d/$img.txt"
}

# check NAME HITS IMG awk-options...: image $AN_DIR/IMG.txt against tests/scenes/analytic.awk's
# formula at the primary hits of $AN_DIR/HITS.hits.txt.
check() {
    local name=$1 hits=$2 img=$3 d=${AN_DIR:-$TMP}; shift 3
    if awk "$@" -f tests/scenes/analytic.awk "$d/$hits.hits.txt" "$d/$img.txt" >"$d/why"; then
        pass "$name ($(cat "$d/why"))"
    else
        fail "$name" "$(tr '\n' ' ' <"$d/why")"
    fi
}
