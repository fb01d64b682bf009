#!/bin/bash
# image-seeds.sh FORMAT DIR: seeds for the image decoder target fuzz_img_FORMAT (png, jpeg, exr,
# tga, hdr) into DIR: small files of that format from Debian's assimp-testmodels when installed
# (PNG, JPEG and TGA textures of third-party models), the images the stage tests write byte by
# byte (tests/stage/textures*.sh, lights.sh), and a few made here for the formats and variants
# the models lack (RLE and colour-mapped TGA, flat and run-length RGBE).
set -eu
fmt=$1 dir=$2
mkdir -p "$dir"
models=/usr/share/assimp/models
hex() { printf "$(echo "$2" | sed 's/../\\x&/g')" >"$dir/$1"; }
# the hex strings NAME=... of a stage script whose name matches PATTERN, each as a seed
from_script() {
    grep -E "^$2=[0-9a-f]+$" "$1" | while IFS== read -r name value; do hex "$name" "$value"; done
}
case $fmt in
png)
    [ -d $models ] && find $models -iname '*.png' -size -64k | head -20 | while read -r f; do
        cp "$f" "$dir/$(echo "$f" | tr / _)"
    done
    from_script tests/stage/textures.sh 'PNG_[A-Z0-9_]+' ;;
jpeg)
    [ -d $models ] && find $models \( -iname '*.jpg' -o -iname '*.jpeg' \) -size -100k | head -10 | while read -r f; do
        cp "$f" "$dir/$(echo "$f" | tr / _)"
    done
    from_script tests/stage/textures-hostile.sh 'JPEG_[0-9]+' ;;
exr)
    from_script tests/stage/lights.sh 'EXR_[A-Z]+'
    from_script tests/stage/textures-hostile.sh 'EXR_[0-9]+' ;;
tga)
    [ -d $models ] && find $models -iname '*.tga' -size -300k | while read -r f; do
        cp "$f" "$dir/$(echo "$f" | tr / _)"
    done
    from_script tests/stage/textures.sh 'TGA_[A-Z]+'
    hex rle32.tga 00000a000000000000000000020002002028820a141e28003240505a
    hex cmap.tga 0001010500020018000000000200010008000102030405060605
    hex rgb16.tga 0000020000000000000000000100010010001f7c ;;
hdr)
    printf '#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n\200\100\000\201\000\000\000\000' >"$dir/flat.hdr"
    printf '#?RGBE\nEXPOSURE=2\n\n+Y 2 +X 1\n\200\200\200\201\100\100\100\201' >"$dir/exposure.hdr"
    printf '#?RADIANCE\n\n-Y 1 +X 8\n\002\002\000\010\210\012\210\024\002\036\037\206\040\210\202' >"$dir/rle.hdr"
    printf '#?RADIANCE\n\n-Y 1 +X 4\n\144\144\144\200\001\001\001\003' >"$dir/oldrle.hdr" ;;
*)
    echo "image-seeds.sh: unknown format '$fmt' (png, jpeg, exr, tga, hdr)" >&2
    exit 2 ;;
esac
