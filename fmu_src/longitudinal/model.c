/* DroneFlyLongitudinal (native): A and B of Sect. 3.5 from the parameters, as
 * dronefly/models/longitudinal_dynamics.py (system_rows, LongitudinalParameters.validate)
 * computes them; the stepping is linear_plant.c's. */
#include "exact.h"
#include <math.h>
#include <stdio.h>
#include "fmu.h"

/* the parameters in the order of LongitudinalParameters' fields */
static const int PARAMS[] = {VR_m_plus, VR_Iy_plus, VR_g_plus, VR_Xu_plus, VR_Xw_plus,
    VR_Xq_plus, VR_Zu_plus, VR_Zw_plus, VR_Zq_plus, VR_Mu_plus, VR_Mw_plus, VR_Mq_plus,
    VR_X_Phi_plus, VR_Z_Phi_plus, VR_M_Phi_plus, VR_X_alpha_1_plus, VR_Z_alpha_1_plus,
    VR_M_alpha_1_plus, VR_X_phibar_plus, VR_Z_phibar_plus, VR_M_phibar_plus,
    VR_X_alpha_2_plus, VR_Z_alpha_2_plus, VR_M_alpha_2_plus};
/* the derivatives of A's rows (X, Z, M) over u, w, q and of B's over the four controls */
static const int STABILITY[3][3] = {{VR_Xu_plus, VR_Xw_plus, VR_Xq_plus},
    {VR_Zu_plus, VR_Zw_plus, VR_Zq_plus}, {VR_Mu_plus, VR_Mw_plus, VR_Mq_plus}};
static const int CONTROL[3][4] = {
    {VR_X_Phi_plus, VR_X_alpha_1_plus, VR_X_phibar_plus, VR_X_alpha_2_plus},
    {VR_Z_Phi_plus, VR_Z_alpha_1_plus, VR_Z_phibar_plus, VR_Z_alpha_2_plus},
    {VR_M_Phi_plus, VR_M_alpha_1_plus, VR_M_phibar_plus, VR_M_alpha_2_plus}};

int plant_matrices(const double *r, double A[PLANT_NX][PLANT_NX],
                   double B[PLANT_NX][PLANT_NU], char *why) {
    char a[32], b[32];
    for (size_t k = 0; k < sizeof PARAMS / sizeof PARAMS[0]; k++)
        if (!isfinite(r[PARAMS[k]])) {
            fmu_repr(a, sizeof a, r[PARAMS[k]]);
            snprintf(why, FMU_WHY, "%s = %s is not finite", VAR_NAME[PARAMS[k]], a);
            return 1;
        }
    const int positive[2] = {VR_m_plus, VR_Iy_plus};
    for (int k = 0; k < 2; k++)
        if (r[positive[k]] <= 0.0) {
            fmu_repr(a, sizeof a, r[positive[k]]);
            snprintf(why, FMU_WHY, "%s = %s must be > 0", VAR_NAME[positive[k]], a);
            return 1;
        }
    double scale[3] = {r[VR_m_plus], r[VR_m_plus], r[VR_Iy_plus]};
    for (int i = 0; i < PLANT_NX; i++) {
        for (int j = 0; j < PLANT_NX; j++) A[i][j] = 0.0;
        for (int j = 0; j < PLANT_NU; j++) B[i][j] = 0.0;
    }
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) A[i][j] = r[STABILITY[i][j]] / scale[i];
        for (int j = 0; j < 4; j++) B[i][j] = r[CONTROL[i][j]] / scale[i];
    }
    A[0][3] = -r[VR_g_plus];
    A[3][2] = 1.0;
    fmu_repr(a, sizeof a, r[VR_m_plus]);
    fmu_repr(b, sizeof b, r[VR_Iy_plus]);
    for (int k = 0; k < 2; k++)
        for (int i = 0; i < PLANT_NX; i++)
            for (int j = 0; j < (k ? PLANT_NU : PLANT_NX); j++) {
                double x = k ? B[i][j] : A[i][j];
                if (!isfinite(x)) {
                    char f[32];
                    fmu_repr(f, sizeof f, x);
                    snprintf(why, FMU_WHY, "%c[%d,%d] = %s is not finite: the parameters "
                             "overflow (m_plus = %s, Iy_plus = %s, or a derivative)",
                             k ? 'B' : 'A', i + 1, j + 1, f, a, b);
                    return 1;
                }
            }
    return 0;
}
