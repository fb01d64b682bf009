# analytic.awk: checks a radiance image against a closed-form answer, pixel by pixel
# (tests/stage/analytic.sh). Two inputs, in this order:
#   1. `pm-info -r` of the direct-vis queries: each pixel's primary hit (position, normal, pixel)
#   2. `pm-exrdump` of the image: "size W H", then "x y r g b" per pixel
#   awk -v kind=point|const -v kd=KD -v I=W_PER_SR [-v lx= -v ly= -v lz=] [-v e=W_PER_M2]
#       [-v le=W_PER_M2_SR] -v tmean=T -v trms=T -v tmax=T -f analytic.awk queries.txt image.txt
# kind=point: E = I |n . (p - l)| / |p - l|^3 + e at each pixel's hit p (direct light of a point
# light at l, plus a uniform e, default 0); kind=const: E = e everywhere. Expected radiance
# L = le + kd / pi * E: the surface's own emission le (default 0) plus Lambertian reflection.
# Checks, on the ratio measured / expected over all channels and pixels:
#   - every pixel has a hit and a finite value (no NaN, no Inf, no pixel missing)
#   - the mean ratio is within tmean of 1, over all pixels and over the brighter and the dimmer
#     half by expected value (so a wrong falloff fails, not only a wrong scale)
#   - the RMS of (ratio - 1) is below trms (the photon noise of one kernel, about 1/sqrt(k))
#   - no pixel's ratio is further than tmax from 1
# Prints one summary line; exits 1 when a check fails.
FNR == NR {
    if ($1 ~ /^[0-9]+$/ && NF >= 11) {
        px = $NF; x = $2; y = $3; z = $4
        if (kind == "point") {
            dx = x - lx; dy = y - ly; dz = z - lz; d2 = dx * dx + dy * dy + dz * dz
            c = ($5 * dx + $6 * dy + $7 * dz) / sqrt(d2); if (c < 0) c = -c
            E = I * c / d2 + e
        } else E = e
        want[px] = le + kd / 3.141592653589793 * E
    }
    next
}
$1 == "size" { w = $2; h = $3; next }
{
    p = $2 * w + $1
    if (!(p in want)) { why = why sprintf(" pixel %d has no hit;", p); bad = 1; next }
    for (c = 3; c <= 5; c++) {
        v = $c
        if (v !~ /^[-+]?[0-9.]+([eE][-+]?[0-9]+)?$/) { why = why sprintf(" pixel %d value %s;", p, v); bad = 1; continue }
        r = v / want[p]
        n++; s += r; ss += (r - 1) ^ 2
        if (n == 1 || r < mn) mn = r
        if (n == 1 || r > mx) mx = r
        val[n] = r; ex[n] = want[p]
    }
    seen++
}
END {
    if (seen != w * h || n == 0) { why = why sprintf(" %d of %d pixels read;", seen, w * h); bad = 1 }
    if (n == 0) { print "no pixels:" why; exit 1 }
    # brighter and dimmer half by expected value: split at the mean of the extremes
    lo = hi = ex[1]
    for (i = 1; i <= n; i++) { if (ex[i] < lo) lo = ex[i]; if (ex[i] > hi) hi = ex[i] }
    cut = (lo + hi) / 2
    for (i = 1; i <= n; i++) if (ex[i] > cut) { sb += val[i]; nb++ } else { sd += val[i]; nd++ }
    mean = s / n; rms = sqrt(ss / n)
    printf "ratio measured/expected: mean %.4f (bright half %s, dim half %s), rms dev %.4f, min %.3f, max %.3f over %d values\n",
        mean, nb ? sprintf("%.4f", sb / nb) : "-", nd ? sprintf("%.4f", sd / nd) : "-", rms, mn, mx, n
    if ((mean - 1) ^ 2 > tmean ^ 2) { why = why " mean off;"; bad = 1 }
    if (nb && (sb / nb - 1) ^ 2 > tmean ^ 2) { why = why " bright half off;"; bad = 1 }
    if (nd && (sd / nd - 1) ^ 2 > tmean ^ 2) { why = why " dim half off;"; bad = 1 }
    if (!(rms <= trms)) { why = why " rms too large;"; bad = 1 }
    if (!(mn >= 1 - tmax && mx <= 1 + tmax)) { why = why " a pixel too far off;"; bad = 1 }
    if (bad) print "failed:" why
    exit bad
}
