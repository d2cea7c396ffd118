/*
 * gen_disort_intensity.c -- writes tests/data/disort_intensity_reference.txt
 *
 * Reference intensities at user angles from converged DISORT (the C port, cdisort, by T. E. Dowling et al.,
 * as distributed with libRadtran) for one homogeneous Henyey-Greenstein layer between black, index-matched
 * boundaries lit by a collimated beam.  This file is only a driver: it contains no DISORT code and calls
 * the library through its public entry points (c_disort_state_alloc, c_disort_out_alloc, c_disort,
 * c_disort_out_free, c_disort_state_free) declared in cdisort.h.
 *
 * Source of cdisort used for the committed data file:
 *   github.com/ashiklom/libradtran (a mirror of libRadtran 2.0.2),
 *   commit 208f5465d6edbbdcef9ad36540316958b0f5d00e, files libsrc_c/cdisort.c, cdisort.h, locate.c, locate.h
 *   (cdisort "Version 2.1.2"; GPL-3; not part of this repository).
 *
 * Build and run (outside the repository; DISORT stays out of the tree):
 *   mkdir -p /tmp/cdisort && cd /tmp/cdisort
 *   #   copy cdisort.c cdisort.h locate.c locate.h from libRadtran's libsrc_c/ into /tmp/cdisort
 *   gcc -O2 -c cdisort.c locate.c
 *   gcc -O2 -I. -o gen_disort_intensity <repo>/tests/data/gen_disort_intensity.c cdisort.o locate.o -lm
 *   ./gen_disort_intensity > <repo>/tests/data/disort_intensity_reference.txt      (about a minute)
 * (gcc 12.2, x86-64, was used for the committed file.)
 *
 * Settings (the same for every problem):
 *   nlyr = 1, usrtau = TRUE with utau = {0, tau}, usrang = TRUE, onlyfl = FALSE, ibcnd = GENERAL_BC,
 *   lamber = TRUE with albedo = 0 (black bottom), planck = FALSE, fisot = 0, spher = FALSE,
 *   fbeam = 1/mu0 (so rfldir(top) = 1: unit irradiance on a horizontal surface), phi0 = 0,
 *   nmom = 1000, pmom[l] = g^l (Henyey-Greenstein), accur = 0 (all nstr azimuthal modes summed),
 *   intensity_correction = TRUE and old_intensity_correction = TRUE (Nakajima-Tanaka TMS + IMS, as in
 *   Fortran DISORT 2.x).  cdisort switches delta-M on by itself whenever pmom[nstr] != 0 (so not for g = 0,
 *   where it is not needed and the intensity correction is skipped too), and it replaces ssalb = 1 by
 *   1 - 100*DBL_EPSILON internally.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdisort.h"

#define NUMU 14
#define NPHI 4
#define NLEV 2
#define NRUN 4

static const double umu_list[NUMU] = {-1.0, -0.999, -0.9, -0.7, -0.5, -0.3, -0.1,
                                      0.1,  0.3,    0.5,  0.7,  0.9,  0.999, 1.0};
static const double phi_list[NPHI] = {0.0, 60.0, 120.0, 180.0};
/* runs: 16, 64, 128 streams and the reference order nref (256, except where cdisort refuses it) */

typedef struct {
    const char *name;
    double g, ssalb, tau, mu0;
    int nref; /* reference number of streams */
} problem;

/* P2: cdisort stops with "beam angle=computational angle" when |mu0 - cmu_i|/mu0 < 1e-4 for a Gauss node
 * cmu_i; for mu0 = 1 the largest node is within 1e-4 of 1 from nstr = 240 on (8.8e-5 at 256), so P2 uses
 * nstr = 224 (largest node 1 - 1.14e-4) as its reference and is cross-checked against nstr = 236. */
static const problem problems[] = {
    {"P1", 0.75, 0.9, 1.0, 0.5, 256},
    {"P2", 0.75, 0.9, 1.0, 1.0, 224},
    {"P3", 0.0, 1.0, 2.0, 0.7, 256},
    {"P4", 0.9, 0.99, 4.0, 0.3, 256},
    {"P5", 0.5, 0.8, 0.1, 0.6, 256},
};
#define NPROB ((int)(sizeof problems / sizeof problems[0]))

typedef struct {
    double uu[NLEV][NUMU][NPHI]; /* level 0 = top (utau = 0), 1 = bottom (utau = tau) */
    double rfldir[NLEV], rfldn[NLEV], flup[NLEV];
} result;

static void run_disort(const problem *p, int nstr, result *r)
{
    disort_state ds;
    disort_output out;
    int l, iu, lu, j;

    memset(&ds, 0, sizeof ds);
    memset(&out, 0, sizeof out);
    strcpy(ds.header, "");

    ds.nstr = nstr;
    ds.nphase = nstr; /* unused with old_intensity_correction */
    ds.nlyr = 1;
    ds.nmom = 1000;
    ds.ntau = NLEV;
    ds.numu = NUMU;
    ds.nphi = NPHI;
    ds.accur = 0.0;

    ds.flag.ibcnd = GENERAL_BC;
    ds.flag.usrtau = TRUE;
    ds.flag.usrang = TRUE;
    ds.flag.lamber = TRUE;
    ds.flag.planck = FALSE;
    ds.flag.spher = FALSE;
    ds.flag.onlyfl = FALSE;
    ds.flag.quiet = QUIET;
    ds.flag.intensity_correction = TRUE;
    ds.flag.old_intensity_correction = TRUE;
    ds.flag.general_source = FALSE;
    ds.flag.output_uum = FALSE;
    ds.flag.brdf_type = BRDF_NONE;
    for (l = 0; l < 5; l++) ds.flag.prnt[l] = FALSE;

    ds.bc.umu0 = p->mu0;
    ds.bc.phi0 = 0.0;
    ds.bc.fbeam = 1.0 / p->mu0;
    ds.bc.fisot = 0.0;
    ds.bc.fluor = 0.0;
    ds.bc.albedo = 0.0;
    ds.bc.btemp = 0.0;
    ds.bc.ttemp = 0.0;
    ds.bc.temis = 1.0;

    c_disort_state_alloc(&ds);
    c_disort_out_alloc(&ds, &out);

    ds.dtauc[0] = p->tau;
    ds.ssalb[0] = p->ssalb;
    for (l = 0; l <= ds.nmom; l++) ds.pmom[l] = (l == 0) ? 1.0 : pow(p->g, (double)l);
    ds.utau[0] = 0.0;
    ds.utau[1] = p->tau;
    for (iu = 0; iu < NUMU; iu++) ds.umu[iu] = umu_list[iu];
    for (j = 0; j < NPHI; j++) ds.phi[j] = phi_list[j];

    c_disort(&ds, &out);

    /* out.uu[iu + (lu + j*ntau)*numu], zero-based */
    for (lu = 0; lu < NLEV; lu++) {
        for (iu = 0; iu < NUMU; iu++)
            for (j = 0; j < NPHI; j++) r->uu[lu][iu][j] = out.uu[iu + (lu + j * ds.ntau) * ds.numu];
        r->rfldir[lu] = out.rad[lu].rfldir;
        r->rfldn[lu] = out.rad[lu].rfldn;
        r->flup[lu] = out.rad[lu].flup;
    }

    c_disort_out_free(&ds, &out);
    c_disort_state_free(&ds);
}

/* The level that carries light for a given sign of umu: upwelling at the top, downwelling at the bottom. */
static int lit_level(int iu) { return umu_list[iu] > 0.0 ? 0 : 1; }

/* max |a-b|/|b| over the lit (level, umu) pairs and all phi */
static double max_rel_lit(const result *a, const result *b)
{
    double m = 0.0;
    int iu, j;
    for (iu = 0; iu < NUMU; iu++)
        for (j = 0; j < NPHI; j++) {
            int lu = lit_level(iu);
            double d = fabs(a->uu[lu][iu][j] - b->uu[lu][iu][j]) / fabs(b->uu[lu][iu][j]);
            if (d > m) m = d;
        }
    return m;
}

/* max |value| over the unlit pairs (downwelling at the top, upwelling at the bottom): should be 0 */
static double max_abs_unlit(const result *a)
{
    double m = 0.0;
    int iu, j;
    for (iu = 0; iu < NUMU; iu++)
        for (j = 0; j < NPHI; j++) {
            double v = fabs(a->uu[1 - lit_level(iu)][iu][j]);
            if (v > m) m = v;
        }
    return m;
}

static double rel(double a, double b) { return fabs(a - b) / fabs(b); }

static double max_rel_flux(const result *a, const result *b)
{
    double m = rel(a->flup[0], b->flup[0]);
    if (rel(a->rfldn[1], b->rfldn[1]) > m) m = rel(a->rfldn[1], b->rfldn[1]);
    if (rel(a->rfldir[1], b->rfldir[1]) > m) m = rel(a->rfldir[1], b->rfldir[1]);
    return m;
}

int main(void)
{
    static result res[NPROB][NRUN], p2_236;
    int ip, k, lu, iu, j;

    for (ip = 0; ip < NPROB; ip++)
        for (k = 0; k < NRUN; k++) {
            const int nstr_list[NRUN] = {16, 64, 128, problems[ip].nref};
            run_disort(&problems[ip], nstr_list[k], &res[ip][k]);
        }
    run_disort(&problems[1], 236, &p2_236);

    printf("# disort_intensity_reference.txt -- written by tests/data/gen_disort_intensity.c (see its header to rebuild)\n");
    printf("# Reference intensities at user angles from converged DISORT, C port (cdisort 2.1.2, T. E. Dowling;\n");
    printf("# Buras, Emde, Kylling additions) as shipped in libRadtran 2.0.2: repository github.com/ashiklom/libradtran,\n");
    printf("# commit 208f5465d6edbbdcef9ad36540316958b0f5d00e, libsrc_c/{cdisort.c,cdisort.h,locate.c,locate.h},\n");
    printf("# built outside this repository with gcc 12.2 -O2 and called through c_disort().\n");
    printf("#\n");
    printf("# Problem: one homogeneous layer, black index-matched top and bottom (lamber, albedo 0), no emission,\n");
    printf("# fisot 0, Henyey-Greenstein phase function given as nmom = 1000 Legendre moments pmom[l] = g^l,\n");
    printf("# collimated beam with fbeam = 1/mu0 and phi0 = 0, so the direct flux on a horizontal surface at the top\n");
    printf("# is exactly 1 (checked: rfldir(utau=0) = 1 in every run).  usrang = TRUE, onlyfl = FALSE, accur = 0\n");
    printf("# (all nstr azimuthal Fourier modes summed), intensity_correction = TRUE with old_intensity_correction\n");
    printf("# = TRUE (Nakajima-Tanaka TMS + IMS, as Fortran DISORT 2.x).  cdisort turns delta-M on by itself when\n");
    printf("# pmom[nstr] != 0; for P3 (g = 0) it is off and so is the intensity correction (nothing to truncate).\n");
    printf("# ssalb = 1 (P3) is accepted; cdisort uses 1 - 100*DBL_EPSILON internally.  mu0 = 1 (P2) is accepted;\n");
    printf("# cdisort then sums only the azimuthal mode m = 0 (the field is azimuth-independent).\n");
    printf("#\n");
    printf("# Intensity = DISORT's uu: diffuse radiance (the direct beam excluded) per unit incident irradiance on a\n");
    printf("# horizontal surface; no factor |umu|, no pi: for an isotropic field I, the hemispherical flux is pi*I.\n");
    printf("# Conventions (DISORT's): umu > 0 upwelling, umu < 0 downwelling; the cosine of the scattering angle is\n");
    printf("# -mu0*umu + sqrt((1-mu0^2)(1-umu^2)) cos(phi - phi0), i.e. phi = phi0 = 0 is the azimuth toward which\n");
    printf("# the beam travels: downwelling at phi = 0 is the forward (transmission) peak, upwelling at phi = 180\n");
    printf("# is the backscatter direction.  Verified separately: a thin layer (g 0.75, albedo 0.01, tau 1e-4, mu0 0.5,\n");
    printf("# nstr 64, same angles) matches single scattering, I = w p(cos)/(4 pi) (1/mu0) mu0/(mu0+umu)\n");
    printf("# [1 - exp(-tau(1/mu0 + 1/umu))] upward at the top and w p(cos)/(4 pi) (1/mu0) mu0/(mu0+umu)\n");
    printf("# [exp(-tau/mu0) - exp(tau/umu)] downward at the bottom (p normalized to 4 pi), to 1.2e-5 relative\n");
    printf("# (the size of the multiple scattering); the other azimuth sign would be off by orders of magnitude.\n");
    printf("#\n");
    printf("# Problems (nref: the reference number of streams, nstr):\n");
    for (ip = 0; ip < NPROB; ip++)
        printf("#   %s  g = %.2f  albedo = %.2f  tau = %.1f  mu0 = %.1f  nref = %d\n", problems[ip].name,
               problems[ip].g, problems[ip].ssalb, problems[ip].tau, problems[ip].mu0, problems[ip].nref);
    printf("# P2 (mu0 = 1) cannot run at nstr = 256: cdisort stops with \"beam angle=computational angle\" when a\n");
    printf("# Gauss node lies within 1e-4 (relative) of mu0, and for mu0 = 1 the largest node does from nstr = 240 on.\n");
    printf("# P2 therefore uses nstr = 224 in the *_256 columns; nstr = 236 (the largest allowed) differs from it by\n");
    printf("# at most %.2e relative (lit intensities) and %.2e (fluxes).\n", max_rel_lit(&p2_236, &res[1][3]),
           max_rel_flux(&p2_236, &res[1][3]));
    printf("#\n");
    printf("# Convergence in the number of streams: max relative difference over the lit values (upwelling at the top,\n");
    printf("# downwelling at the bottom, all umu and phi; 56 values per problem), against nref:\n");
    printf("#   problem   nstr=128 vs nref   nstr=64 vs nref   nstr=16 vs nref   fluxes 128 vs nref\n");
    for (ip = 0; ip < NPROB; ip++)
        printf("#   %s        %.2e           %.2e          %.2e          %.2e\n", problems[ip].name,
               max_rel_lit(&res[ip][2], &res[ip][3]), max_rel_lit(&res[ip][1], &res[ip][3]),
               max_rel_lit(&res[ip][0], &res[ip][3]), max_rel_flux(&res[ip][2], &res[ip][3]));
    {
        double m = 0.0, d = 0.0;
        for (ip = 0; ip < NPROB; ip++)
            for (k = 0; k < NRUN; k++) {
                double v = max_abs_unlit(&res[ip][k]);
                double e = fabs(res[ip][k].rfldir[0] - 1.0);
                if (v > m) m = v;
                if (e > d) d = e;
            }
        printf("# Unlit values (downwelling at the top, upwelling at the bottom; black boundaries): max |I| = %.1e.\n", m);
        printf("# max |rfldir(top) - 1| over all runs = %.1e.\n", d);
        printf("# P3 (albedo 1 - 100 DBL_EPSILON) sits at a floor of ~1e-9: nstr = 96..240 all differ from 256 by 4e-10 to\n");
        printf("# 3e-9 without a trend (near-conservative eigenvalue); with albedo 0.999999 128 vs 256 is 4e-11.\n");
        printf("# So the reference intensities are good to ~1e-8 relative or better (P2: 236 vs 224 above).\n");
        printf("# Energy check, P3 (conservative): flup_top + rfldn_bottom + rfldir_bottom - 1 = %.1e.\n",
               res[2][3].flup[0] + res[2][3].rfldn[1] + res[2][3].rfldir[1] - 1.0);
    }
    printf("#\n");
    printf("# Intensity lines -- columns: problem level umu phi_deg intensity_256 intensity_16\n");
    printf("#   level: top (utau = 0) or bottom (utau = tau); both levels are listed for every umu, the unlit ones\n");
    printf("#   (top with umu < 0, bottom with umu > 0) are 0 up to rounding.  intensity_256: nstr = nref (256; 224 for P2),\n");
    printf("#   the reference; intensity_16: nstr = 16 (for comparing a 16-stream solver with DISORT at equal order).\n");
    printf("# Flux lines -- columns: flux problem flup_top rfldn_bottom rfldir_bottom   (nstr = nref)\n");
    printf("#   flup_top: diffuse upward flux at utau = 0; rfldn_bottom: diffuse downward flux at utau = tau;\n");
    printf("#   rfldir_bottom: direct-beam flux at utau = tau (= exp(-tau/mu0)).\n");

    for (ip = 0; ip < NPROB; ip++)
        for (lu = 0; lu < NLEV; lu++)
            for (iu = 0; iu < NUMU; iu++)
                for (j = 0; j < NPHI; j++)
                    printf("%s %s %g %g %.12e %.12e\n", problems[ip].name, lu == 0 ? "top" : "bottom", umu_list[iu],
                           phi_list[j], res[ip][3].uu[lu][iu][j], res[ip][0].uu[lu][iu][j]);
    for (ip = 0; ip < NPROB; ip++)
        printf("flux %s %.12e %.12e %.12e\n", problems[ip].name, res[ip][3].flup[0], res[ip][3].rfldn[1],
               res[ip][3].rfldir[1]);
    return 0;
}
