# energy.awk: checks the power a photons file carries, bounce by bounce, against a closed
# scene's known answer (used by tests/stage/photons.sh on `pm-info -r` output).
#   awk -v n=EMITTED -v phi=TOTAL_W -v rho=ALBEDO -v dmax=D [-v exact0=1] -f energy.awk
# Column 5-7 are the RGB power, the last column the depth. In a closed scene of albedo rho
# the photons of bounce d carry phi rho^d on average. Each emitted path stores at most one
# photon per bounce, so the sum at bounce d is a sum of n independent path values and its
# standard error is sqrt(sum p^2 - (sum p)^2 / n). A bounce passes within 5 standard
# errors; bounce 0 (every path's first hit) must match phi to 1e-5 when exact0 is set.
/^#/ || $1 !~ /^[0-9]+$/ || NF < 11 { next }
{
    p = $5 + $6 + $7; d = $NF
    s[d] += p; q[d] += p * p
}
END {
    bad = 0
    for (d = 0; d <= dmax; d++) {
        want = phi * rho ^ d
        se = sqrt((q[d] - s[d] * s[d] / n) > 0 ? q[d] - s[d] * s[d] / n : 0)
        tol = (d == 0 && exact0) ? 1e-5 * phi : 5 * se + 1e-9 * phi
        diff = s[d] - want; if (diff < 0) diff = -diff
        printf "bounce %d: %.6g W (expected %.6g, tolerance %.3g)\n", d, s[d], want, tol
        if (!(diff <= tol)) bad = 1
    }
    exit bad
}
