/* unit_stats.c: the chi-square test that the sampler tests share (test_bsdf.c, test_transport.c):
 * one definition of how bins are pooled and where the bound lies. */
#include <math.h>

#include "unit.h"

double unit_chi2_pooled(const char *name, const double *obs, const double *prob, int nbins, double n, int *dof)
{
    double chi2 = 0.0, pool_o = 0.0, pool_e = 0.0;
    int bins = 0;
    for (int i = 0; i < nbins; i++) {
        double e = prob[i] * n;
        /* A sample where the pdf puts (almost) nothing: the sampler and its pdf disagree on the
         * support, which no chi-square over the other bins would show. */
        if (e < 1e-3 && obs[i] > 0)
            fail_msg("%s: %.0f samples in bin %d, where the pdf expects %.2g", name, obs[i], i, e);
        if (e >= 5.0) {
            chi2 += (obs[i] - e) * (obs[i] - e) / e;
            bins++;
        } else {
            pool_o += obs[i], pool_e += e;
        }
    }
    if (pool_e >= 5.0) {
        chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        bins++;
    }
    *dof = bins - 1;
    return chi2;
}

void unit_check_chi2(const char *name, double chi2, int dof)
{
    double bound = dof + 5.0 * sqrt(2.0 * dof);
    if (!(chi2 <= bound))
        fail_msg("%s: chi-square %.1f over %d degrees of freedom (bound %.1f)", name, chi2, dof, bound);
}
