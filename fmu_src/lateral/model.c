/* DroneFlyLateral (native): A1 and B1 of Eq. (9) from the parameters by Eqs. (10)-(11), as
 * dronefly/models/lateral_dynamics.py (system_rows, LateralParameters.validate) computes
 * them; the stepping is linear_plant.c's. */
#include "exact.h"
#include <math.h>
#include <stdio.h>
#include "fmu.h"

/* the parameters in the order of LateralParameters' fields */
static const int PARAMS[] = {VR_m_plus, VR_Ix_plus, VR_Iz_plus, VR_Ixz_plus, VR_g_plus,
    VR_Yv_plus, VR_Yp_plus, VR_Yr_plus, VR_Lv_plus, VR_Lp_plus, VR_Lr_plus, VR_Nv_plus,
    VR_Np_plus, VR_Nr_plus, VR_Y_Phi_a_plus, VR_L_Phi_a_plus, VR_N_Phi_a_plus,
    VR_Y_alpha_1a_plus, VR_L_alpha_1a_plus, VR_N_alpha_1a_plus, VR_Y_alpha_2a_plus,
    VR_L_alpha_2a_plus, VR_N_alpha_2a_plus};
/* (Y, L, N) per column of A1 (v, p, r) and of B1 (the three controls) */
static const int STABILITY[3][3] = {{VR_Yv_plus, VR_Lv_plus, VR_Nv_plus},
    {VR_Yp_plus, VR_Lp_plus, VR_Np_plus}, {VR_Yr_plus, VR_Lr_plus, VR_Nr_plus}};
static const int CONTROL[3][3] = {{VR_Y_Phi_a_plus, VR_L_Phi_a_plus, VR_N_Phi_a_plus},
    {VR_Y_alpha_1a_plus, VR_L_alpha_1a_plus, VR_N_alpha_1a_plus},
    {VR_Y_alpha_2a_plus, VR_L_alpha_2a_plus, VR_N_alpha_2a_plus}};

int plant_matrices(const double *r, double A[PLANT_NX][PLANT_NX],
                   double B[PLANT_NX][PLANT_NU], char *why) {
    char a[32], b[32], d[32], e[32];
    for (size_t k = 0; k < sizeof PARAMS / sizeof PARAMS[0]; k++)
        if (!isfinite(r[PARAMS[k]])) {
            fmu_repr(a, sizeof a, r[PARAMS[k]]);
            snprintf(why, FMU_WHY, "%s = %s is not finite", VAR_NAME[PARAMS[k]], a);
            return 1;
        }
    double m = r[VR_m_plus], Ix = r[VR_Ix_plus], Iz = r[VR_Iz_plus], Ixz = r[VR_Ixz_plus];
    fmu_repr(a, sizeof a, m);
    fmu_repr(b, sizeof b, Ix);
    fmu_repr(d, sizeof d, Iz);
    fmu_repr(e, sizeof e, Ixz);
    if (m <= 0.0) {
        snprintf(why, FMU_WHY, "m_plus = %s must be > 0", a);
        return 1;
    }
    if (Ix <= 0.0 || Iz <= 0.0) {
        snprintf(why, FMU_WHY, "Ix_plus = %s, Iz_plus = %s must be > 0", b, d);
        return 1;
    }
    double check = Ix * Iz - Ixz * Ixz;
    if (!isfinite(check)) {
        char f[32];
        fmu_repr(f, sizeof f, check);
        snprintf(why, FMU_WHY, "Ix_plus*Iz_plus - Ixz_plus^2 = %s is not finite (Ix_plus = %s, "
                 "Iz_plus = %s, Ixz_plus = %s)", f, b, d, e);
        return 1;
    }
    if (check <= 0.0) {
        char f[32], g[32];
        fmu_repr(f, sizeof f, Ix * Iz);
        fmu_repr(g, sizeof g, Ixz * Ixz);
        snprintf(why, FMU_WHY, "Ix_plus*Iz_plus = %s must exceed Ixz_plus^2 = %s (Ixz_plus = %s)",
                 f, g, e);
        return 1;
    }
    double det = Ix * Iz - pow(Ixz, 2.0); /* (Python: Ixz_plus**2, libm's pow) */
    for (int i = 0; i < PLANT_NX; i++) {
        for (int j = 0; j < PLANT_NX; j++) A[i][j] = 0.0;
        for (int j = 0; j < PLANT_NU; j++) B[i][j] = 0.0;
    }
    for (int j = 0; j < 3; j++) {
        double Y = r[STABILITY[j][0]], L = r[STABILITY[j][1]], N = r[STABILITY[j][2]];
        A[0][j] = Y / m;
        A[1][j] = (Iz * L + Ixz * N) / det;
        A[2][j] = (Ixz * L + Ix * N) / det;
        Y = r[CONTROL[j][0]], L = r[CONTROL[j][1]], N = r[CONTROL[j][2]];
        B[0][j] = Y / m;
        B[1][j] = (Iz * L + Ixz * N) / det;
        B[2][j] = (Ixz * L + Ix * N) / det;
    }
    A[0][3] = r[VR_g_plus];
    A[3][1] = 1.0;
    for (int k = 0; k < 2; k++)
        for (int i = 0; i < PLANT_NX; i++)
            for (int j = 0; j < (k ? PLANT_NU : PLANT_NX); j++) {
                double x = k ? B[i][j] : A[i][j];
                if (!isfinite(x)) {
                    char f[32];
                    fmu_repr(f, sizeof f, x);
                    snprintf(why, FMU_WHY, "%c[%d,%d] = %s is not finite: the parameters "
                             "overflow Eqs. (10)-(11) (m_plus = %s, Ix_plus = %s, Iz_plus = %s, "
                             "Ixz_plus = %s, or a derivative)", k ? 'B' : 'A', i + 1, j + 1, f,
                             a, b, d, e);
                    return 1;
                }
            }
    return 0;
}
