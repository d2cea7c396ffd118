/*
 * gen_disort_aureole.c -- writes tests/data/disort_aureole_reference.txt
 *
 * Downwelling radiance at the bottom of a Henyey-Greenstein slab near the direction of the transmitted beam (the
 * aureole, where Nakajima and Tanaka's IMS correction acts), from DISORT's C port (cdisort), for
 * tests/test_layer_intensity.cpp.  This file is only a driver: it contains no DISORT code and calls the library
 * through its public entry points declared in cdisort.h.  Source, build and run as for gen_disort_intensity.c
 * (the same cdisort 2.1.2 files, github.com/ashiklom/libradtran at 208f5465d6edbbdcef9ad36540316958b0f5d00e):
 *   gcc -O2 -c cdisort.c locate.c
 *   gcc -O2 -I. -o gen_disort_aureole <repo>/tests/data/gen_disort_aureole.c cdisort.o locate.o -lm
 *   ./gen_disort_aureole > <repo>/tests/data/disort_aureole_reference.txt      (about 15 seconds)
 *
 * Settings as gen_disort_intensity.c (black index-matched faces, fbeam = 1/mu0, phi0 = 0, nmom = 1000 moments
 * g^l, accur = 0, intensity_correction = old_intensity_correction = TRUE: TMS, and IMS within 10 degrees of the
 * beam's polar angle), at 256 streams (the reference: delta-M's f = g^256, 2e-12 and 2e-6, makes both corrections
 * negligible) and at 32 and 16 streams (DISORT's own values with its corrections, which stratum's M = 16 and 8
 * should reproduce inside the 10-degree window, where both codes solve the same discrete equations).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cdisort.h"

#define NDELTA 9
#define NPHI 5
static const double delta_deg[NDELTA] = {-9, -6, -3, -1, 0, 1, 3, 6, 9}; /* polar offsets from the beam's */
static const double phi_list[NPHI] = {0.0, 2.0, 5.0, 10.0, 20.0};

typedef struct {
    const char *name;
    double g, ssalb, tau, mu0;
} problem;
static const problem problems[] = {
    {"A1", 0.9, 0.99, 4.0, 0.3}, /* P4 of disort_intensity_reference.txt */
    {"A2", 0.95, 0.9, 1.0, 0.8},
};

static void run(const problem *p, int nstr, const double *umu, double uu[NDELTA][NPHI])
{
    disort_state ds;
    disort_output out;
    int l, iu, j;
    memset(&ds, 0, sizeof ds);
    memset(&out, 0, sizeof out);
    ds.nstr = nstr;
    ds.nphase = nstr;
    ds.nlyr = 1;
    ds.nmom = 1000;
    ds.ntau = 1;
    ds.numu = NDELTA;
    ds.nphi = NPHI;
    ds.accur = 0.0;
    ds.flag.ibcnd = GENERAL_BC;
    ds.flag.usrtau = TRUE;
    ds.flag.usrang = TRUE;
    ds.flag.lamber = TRUE;
    ds.flag.quiet = TRUE;
    ds.flag.intensity_correction = TRUE;
    ds.flag.old_intensity_correction = TRUE;
    ds.flag.brdf_type = BRDF_NONE;
    ds.bc.umu0 = p->mu0;
    ds.bc.fbeam = 1.0 / p->mu0;
    ds.bc.temis = 1.0;
    c_disort_state_alloc(&ds);
    c_disort_out_alloc(&ds, &out);
    ds.dtauc[0] = p->tau;
    ds.ssalb[0] = p->ssalb;
    for (l = 0; l <= ds.nmom; l++) ds.pmom[l] = (l == 0) ? 1.0 : pow(p->g, (double)l);
    ds.utau[0] = p->tau;
    for (iu = 0; iu < NDELTA; iu++) ds.umu[iu] = umu[iu];
    for (j = 0; j < NPHI; j++) ds.phi[j] = phi_list[j];
    c_disort(&ds, &out);
    for (iu = 0; iu < NDELTA; iu++)
        for (j = 0; j < NPHI; j++) uu[iu][j] = out.uu[iu + j * ds.ntau * ds.numu];
    c_disort_out_free(&ds, &out);
    c_disort_state_free(&ds);
}

int main(void)
{
    int i, iu, j;
    printf("# disort_aureole_reference.txt -- written by tests/data/gen_disort_aureole.c (see its header to rebuild)\n");
    printf("# DISORT's C port (cdisort 2.1.2 in libRadtran 2.0.2, github.com/ashiklom/libradtran at 208f546),\n");
    printf("# downwelling radiance at the bottom (utau = tau) near the transmitted beam, per unit irradiance on a\n");
    printf("# horizontal surface (fbeam = 1/mu0), black index-matched faces, Henyey-Greenstein moments g^l (nmom 1000),\n");
    printf("# TMS + IMS (old_intensity_correction; IMS within 10 degrees of the beam's polar angle).\n");
    printf("# Directions (DISORT's): umu < 0 down, phi the azimuth from the beam's direction of travel.\n");
    printf("# columns: problem g albedo tau mu0 umu phi I(256 streams) I(32 streams) I(16 streams)\n");
    for (i = 0; i < (int)(sizeof problems / sizeof problems[0]); i++) {
        const problem *p = &problems[i];
        double umu[NDELTA], ref[NDELTA][NPHI], s32[NDELTA][NPHI], s16[NDELTA][NPHI];
        const double theta0 = acos(p->mu0) * 180.0 / M_PI;
        for (iu = 0; iu < NDELTA; iu++) /* ascending umu: from the steepest downward direction */
            umu[iu] = -cos((theta0 + delta_deg[iu]) * M_PI / 180.0);
        run(p, 256, umu, ref);
        run(p, 32, umu, s32);
        run(p, 16, umu, s16);
        for (iu = 0; iu < NDELTA; iu++)
            for (j = 0; j < NPHI; j++)
                printf("%s %.2f %.2f %.1f %.2f %.12f %.1f %.12e %.12e %.12e\n", p->name, p->g, p->ssalb, p->tau, p->mu0,
                       umu[iu], phi_list[j], ref[iu][j], s32[iu][j], s16[iu][j]);
    }
    return 0;
}
