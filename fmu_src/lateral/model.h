/* DroneFlyLateral (native): the lateral plant of Eq. (9), a linear plant (linear_plant.h). */
#ifndef DRONEFLY_MODEL_H
#define DRONEFLY_MODEL_H
#define PLANT_NU 3
#define PLANT_U0 VR_delta_Phi_a
#define PLANT_X0 VR_delta_v
#define PLANT_START0 VR_delta_v_start
#define PLANT_A0 VR_A_1_1
#define PLANT_B0 VR_B_1_1
#define PLANT_A_NAME "A1"
#define PLANT_B_NAME "B1"
/* x = x+ * scale: delta_v by U, delta_p and delta_r by n, delta_gamma by 1 */
#define PLANT_SCALES {SCALE_U, SCALE_N, SCALE_N, SCALE_ONE}
#include "linear_plant.h"
typedef PlantState ModelState;
#endif
