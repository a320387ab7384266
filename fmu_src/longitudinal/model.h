/* DroneFlyLongitudinal (native): the longitudinal plant of Sect. 3.5, a linear plant
 * (linear_plant.h). */
#ifndef DRONEFLY_MODEL_H
#define DRONEFLY_MODEL_H
#define PLANT_NU 4
#define PLANT_U0 VR_delta_Phi
#define PLANT_X0 VR_delta_u
#define PLANT_START0 VR_delta_u_start
#define PLANT_A0 VR_A_1_1
#define PLANT_B0 VR_B_1_1
#define PLANT_A_NAME "A"
#define PLANT_B_NAME "B"
/* x = x+ * scale: delta_u and delta_w by U, delta_q by n, delta_theta by 1 */
#define PLANT_SCALES {SCALE_U, SCALE_U, SCALE_N, SCALE_ONE}
#include "linear_plant.h"
typedef PlantState ModelState;
#endif
