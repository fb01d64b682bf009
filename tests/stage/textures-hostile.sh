# textures-hostile.sh: hostile and disguised image files (issue 28 item 3) through the scene
# loader (scene-info), each one line naming the file and the value, exit 1, no crash, no wait:
#   a truncated 24-bit TGA (stb_image filled the rest with uninitialised memory); a PNG and a
#   BMP named .tga (stb_image decoded them); headers declaring huge TGA, JPEG, PNG and OpenEXR
#   images (gigabytes from a few bytes), refused against the texture budget before any
#   allocation; a cut JPEG (libjpeg's warning was dropped and the texture was grey); a FIFO
#   named as a texture and as a sky map (open blocked); image_budgets in the scene file (per
#   texture, over all textures, bad values); a Radiance .hdr sky map (read as OpenEXR before).
# The images are written byte by byte (made once with libjpeg, zlib and pm_exr_write_rgb).
# 16 x 16 RGB baseline JPEG; its SOF0 (ffc0 0011 08 HHHH WWWW 03) is patched below
# programs: scene-info trace-gather-points composite
JPEG_16=ffd8ffe000104a46494600010100000100010000ffdb0043000302020302020303030304030304050805050404050a070706080c0a0c0c0b0a0b0b0d0e12100d0e110e0b0b1016101113141515150c0f171816141812141514ffdb00430103040405040509050509140d0b0d1414141414141414141414141414141414141414141414141414141414141414141414141414141414141414141414141414ffc00011080010001003012200021101031101ffc4001f0000010501010101010100000000000000000102030405060708090a0bffc400b5100002010303020403050504040000017d01020300041105122131410613516107227114328191a1082342b1c11552d1f02433627282090a161718191a25262728292a3435363738393a434445464748494a535455565758595a636465666768696a737475767778797a838485868788898a92939495969798999aa2a3a4a5a6a7a8a9aab2b3b4b5b6b7b8b9bac2c3c4c5c6c7c8c9cad2d3d4d5d6d7d8d9dae1e2e3e4e5e6e7e8e9eaf1f2f3f4f5f6f7f8f9faffc4001f0100030101010101010101010000000000000102030405060708090a0bffc400b51100020102040403040705040400010277000102031104052131061241510761711322328108144291a1b1c109233352f0156272d10a162434e125f11718191a262728292a35363738393a434445464748494a535455565758595a636465666768696a737475767778797a82838485868788898a92939495969798999aa2a3a4a5a6a7a8a9aab2b3b4b5b6b7b8b9bac2c3c4c5c6c7c8c9cad2d3d4d5d6d7d8d9dae2e3e4e5e6e7e8e9eaf2f3f4f5f6f7f8f9faffda000c03010002110311003f00f957c29f0a7ee7ee7f4af66f09fc29fb9fb9fd2bd8bc27f0a7ee7ee7f4af66f0a7c29fb9fb9fd2baf39e30dfde27c36e3df83dfec7ffd9
# a PNG signature and an IHDR of 30000 x 30000 RGB (valid CRC)
PNG_HUGE=89504e470d0a1a0a0000000d4948445200007530000075300802000000e9456fed
# 2 x 2 half RGB OpenEXR, uncompressed; its dataWindow (box2i 0 0 1 1) is patched below
EXR_2=762f3101020000007479706500737472696e67000d0000007363616e6c696e65696d6167656e616d6500737472696e670003000000726762636f6d7072657373696f6e00636f6d7072657373696f6e0001000000006461746157696e646f7700626f783269001000000000000000000000000100000001000000646973706c617957696e646f7700626f7832690010000000000000000000000001000000010000006c696e654f72646572006c696e654f72646572000100000000706978656c417370656374526174696f00666c6f617400040000000000803f73637265656e57696e646f7743656e746572007632660008000000000000000000000073637265656e57696e646f77576964746800666c6f617400040000000000803f6368616e6e656c730063686c6973740037000000420001000000000000000100000001000000470001000000000000000100000001000000520001000000000000000100000001000000000079010000000000008d01000000000000000000000c000000cd34cd3866320038662e6636010000000c000000333b0034663a00389a39003c
# 4 x 1 grey PNG (textures.sh)
PNG_AB=89504e470d0a1a0a0000000d4948445200000004000000010800000000dc5750110000000d4944415478da63f8ffbfa10100087e02ff36d0234f0000000049454e44ae426082
bin_file() { printf "$(echo "$2" | sed 's/../\\x&/g')" >"$1"; }
# tga FILE TYPE W H BPP [PIXEL-HEX]: an 18-byte TGA header (sizes little-endian) and pixels
tga() {
    local le_w le_h
    le_w=$(printf '%04x' "$3" | sed 's/\(..\)\(..\)/\2\1/')
    le_h=$(printf '%04x' "$4" | sed 's/\(..\)\(..\)/\2\1/')
    bin_file "$1" "0000$(printf '%02x' "$2")000000000000000000$le_w$le_h$(printf '%02x' "$5")00${6:-}"
}

# plane DIR MAP [TOP-LEVEL-JSON]: a textured quad whose map_Kd is MAP, and its scene.json
plane() {
    mkdir -p "$1"
    printf 'mtllib p.mtl\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl paint\nf 1/1 4/4 3/3 2/2\n' >"$1/p.obj"
    printf 'newmtl paint\nKd 0.8 0.8 0.8\nmap_Kd %s\n' "$2" >"$1/p.mtl"
    cat >"$1/scene.json" <<JSON
{ "pmtk_scene": 1, "name": "hostile", "meshes": [ { "file": "p.obj" } ],
  "camera": { "eye": [0, 1, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_y": 90, "width": 8, "height": 8 },
  "point_lights": [ { "position": [0, 1, 0], "intensity": [1, 1, 1] } ] ${3:+, $3} }
JSON
}

# hostile NAME PATTERN FILE [TOP-LEVEL-JSON]: scene-info on a plane textured with FILE (already
# in $TMP/NAME-dir) fails with one line matching PATTERN within 20 s (timeout: exit 124).
hostile() {
    local dir="$TMP/$1"
    plane "$dir" "$3" "${4:-}"
    expect_error "$1" "$2" timeout 20 "$BIN/scene-info" -q "$dir/scene.json"
}

# 1. truncated 24-bit TGA: 4 x 4 declared, 20 of 48 bytes of pixels
mkdir -p "$TMP/cut-tga"
tga "$TMP/cut-tga/t.tga" 2 4 4 24 "$(printf '55%.0s' $(seq 20))"
hostile cut-tga "texture '.*t\.tga': truncated TGA: 20 bytes of pixels for 4 x 4 at 24 bits \(48\)" t.tga

# 2. disguised: a PNG and a BMP named .tga
mkdir -p "$TMP/png-tga" "$TMP/bmp-tga"
bin_file "$TMP/png-tga/t.tga" "$PNG_AB"
hostile png-tga "texture '.*t\.tga': named as TGA but holds a PNG image" t.tga
bin_file "$TMP/bmp-tga/t.tga" 424d3a000000000000003600000028000000010000000100000001001800000000000400000000000000000000000000000000000000ffffff00
hostile bmp-tga "texture '.*t\.tga': a BMP image named as TGA; a texture is read from PNG, JPEG, OpenEXR, TGA: convert it" t.tga

# 3. huge declared sizes: TGA 23170 x 23170 (18 bytes), JPEG 65500 x 65500, PNG 30000 x 30000,
# OpenEXR data window 40000 x 40000: each refused against the budget, before allocation
mkdir -p "$TMP/huge-tga" "$TMP/huge-jpg" "$TMP/huge-png" "$TMP/huge-exr"
tga "$TMP/huge-tga/t.tga" 2 23170 23170 24
hostile huge-tga "texture '.*t\.tga': 23170 x 23170 pixels would take 2047\.9 MiB decoded, above its budget \(image_budgets\.texture_mib 256\)" t.tga
bin_file "$TMP/huge-jpg/t.jpg" "$(echo "$JPEG_16" | sed 's/ffc00011080010001003/ffc0001108ffdcffdc03/')"
hostile huge-jpg "texture '.*t\.jpg': 65500 x 65500 pixels would take 16366\.0 MiB decoded, above its budget" t.jpg
bin_file "$TMP/huge-png/t.png" "${PNG_HUGE}0000000049444154""35af061e" # and an empty IDAT
hostile huge-png "texture '.*t\.png': 30000 x 30000 pixels would take 3433\.2 MiB decoded, above its budget" t.png
bin_file "$TMP/huge-exr/t.exr" "$(echo "$EXR_2" | sed 's/\(6461746157696e646f7700626f78326900100000000000000000000000\)0100000001000000/\1409c0000409c0000/')"
hostile huge-exr "OpenEXR image '.*t\.exr': data window of 40001x40001 pixels is above the budget of 16777216 pixels" t.exr

# 4. a cut JPEG: an error, not grey texels
mkdir -p "$TMP/cut-jpg"
bin_file "$TMP/cut-jpg/t.jpg" "${JPEG_16:0:$((${#JPEG_16} - 80))}"
hostile cut-jpg "texture '.*t\.jpg': libjpeg: Premature end of JPEG file" t.jpg

# 5. FIFOs named as a texture and as a sky map: refused at once, not waited on
mkdir -p "$TMP/fifo"
mkfifo "$TMP/fifo/t.png" "$TMP/fifo/sky.hdr"
hostile fifo "texture '.*t\.png' is not a regular file \(a FIFO\)" t.png
mkdir -p "$TMP/fifo-sky"
bin_file "$TMP/fifo-sky/t.png" "$PNG_AB"
hostile fifo-sky "sky\.map '\.\./fifo/sky\.hdr': sky map '.*sky\.hdr' is not a regular file \(a FIFO\)" t.png \
    '"sky": { "map": "../fifo/sky.hdr" }'

# 6. image_budgets: one texture of 16 bytes fits 0.00002 MiB (20 bytes), one of 4 x 4 x 4 = 64
# bytes does not; two of 64 bytes fit textures_mib 0.00015 (157 bytes), a third does not; bad values and keys name themselves
mkdir -p "$TMP/budget"
bin_file "$TMP/budget/ab.png" "$PNG_AB"
tga "$TMP/budget/a.tga" 3 4 4 8 "$(printf '80%.0s' $(seq 16))"
plane "$TMP/budget/ok" ../ab.png '"image_budgets": { "texture_mib": 0.00002 }'
expect_exit "image_budgets.texture_mib 0.00002 holds a 4 x 1 PNG (16 bytes)" 0 "$BIN/scene-info" -q "$TMP/budget/ok/scene.json"
mv "$TMP/budget/a.tga" "$TMP/budget-a.tga"
hostile budget "texture '.*a\.tga': 4 x 4 pixels would take 0\.0 MiB decoded, above its budget \(image_budgets\.texture_mib 2e-05\)" \
    ../budget-a.tga '"image_budgets": { "texture_mib": 0.00002 }'
mkdir -p "$TMP/budget-all"
for n in 1 2 3; do tga "$TMP/budget-all/t$n.tga" 3 4 4 8 "$(printf "0$n%.0s" $(seq 16))"; done
plane "$TMP/budget-all" t1.tga '"image_budgets": { "textures_mib": 0.00015 }'
printf 'mtllib p.mtl\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nusemtl a\nf 1/1 3/3 2/2\nusemtl b\nf 1/1 3/3 2/2\nusemtl c\nf 1/1 3/3 2/2\n' >"$TMP/budget-all/p.obj"
printf 'newmtl a\nKd 1 1 1\nmap_Kd t1.tga\nnewmtl b\nKd 1 1 1\nmap_Kd t2.tga\nnewmtl c\nKd 1 1 1\nmap_Kd t3.tga\n' >"$TMP/budget-all/p.mtl"
expect_error "image_budgets.textures_mib over all textures" \
    "texture '.*t3\.tga': 4 x 4 pixels would take 0\.0 MiB decoded, above its budget \(image_budgets\.textures_mib 0\.00015 over all textures, 128 bytes of it taken\)" \
    "$BIN/scene-info" -q "$TMP/budget-all/scene.json"
hostile budget-neg "image_budgets\.texture_mib.*-1" ../budget-a.tga '"image_budgets": { "texture_mib": -1 }'
hostile budget-key "image_budgets: unknown key 'texture_bytes'" ../budget-a.tga '"image_budgets": { "texture_bytes": 1 }'

# 7. a Radiance .hdr sky map: 2 x 1 RGBE (128 128 128, exponent 129) = 128.5 / 128 = 1.00390625
# everywhere, times sky.radiance 0.5: every camera ray that escapes sees 0.501953125
mkdir -p "$TMP/hdr"
printf '#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n\x80\x80\x80\x81\x80\x80\x80\x81' >"$TMP/hdr/sky.hdr"
bin_file "$TMP/hdr/ab.png" "$PNG_AB"
plane "$TMP/hdr" ab.png '"sky": { "map": "sky.hdr", "radiance": [0.5, 0.5, 0.5] }'
sed -i 's/"eye": \[0, 1, 0\], "look_at": \[0, 0, 0\]/"eye": [0, 1, 0], "look_at": [0, 2, 0]/' "$TMP/hdr/scene.json"
if "$BIN/trace-gather-points" "$TMP/hdr/scene.json" --spp 4 -q -o "$TMP/hdr/q.pm" --direct "$TMP/hdr/d.pm" &&
    "$BIN/composite" "$TMP/hdr/d.pm" -q -o "$TMP/hdr/d.exr" && "$BUILD/tests/pm-exrdump" "$TMP/hdr/d.exr" >"$TMP/hdr/d.txt" &&
    awk 'NR > 1 { n++; for (c = 3; c <= 5; c++) if ($c < 0.501953 || $c > 0.501954) bad++ } END { exit !(n == 64 && !bad) }' "$TMP/hdr/d.txt"; then
    pass "Radiance .hdr sky map: 64 escaping camera rays see 1.00390625 x 0.5"
else
    fail "Radiance .hdr sky map" "$(head -c 300 "$TMP/hdr/d.txt") $(head -c 300 "$TMP/err" 2>/dev/null)"
fi
# ... and refused by a sky map budget below its 2 x 36 bytes (pixels and sampling tables)
sed 's/"sky": {/"image_budgets": { "sky_map_mib": 0.00005 }, "sky": {/' "$TMP/hdr/scene.json" >"$TMP/hdr/small.json"
expect_error "image_budgets.sky_map_mib" \
    "sky\.map 'sky\.hdr': sky map '.*sky\.hdr': 2 x 1 pixels would take 0\.0 MiB decoded, above its budget \(image_budgets\.sky_map_mib: 52 bytes for the pixels and their sampling tables\)" \
    "$BIN/scene-info" -q "$TMP/hdr/small.json"
