/*
 * The model's C (src/model.c, built with a MODEL header) behind a line-oriented pipe, for the
 * pytest cross-checks against PostureModel.predict (tests/papers/takuma2014/test_export_model.py).
 * One request per input line, one answer line per request:
 *
 *   P <P0_L1> <P0_R1> <P0_L2> <P0_R2> <P_L1> <P_R1> <P_L2> <P_R2> <theta1_0> <theta2_0> [<m1> <m2>]
 *       ->  theta1 theta2 Fx Fy se_theta1 se_theta2 se_Fx se_Fy flags
 *       (m1, m2: the joints' motion into the baseline, for a model with the friction terms; none: unknown)
 *   E <x>                  ->  model_erf(x) and its slope
 *   C <channel> <counts>   ->  the channel's value in MPa or rad
 *   I                      ->  the model's id, quantities and channel names
 */
#include <stdio.h>
#include <stdlib.h>

#include "model.h"

int main(void)
{
    char req[1024];
    while (fgets(req, sizeof req, stdin)) {
        if (req[0] == 'P') {
            float x[12];
            char *p = req + 1, *end;
            int n = 0;
            for (; n < 12; n++) {
                x[n] = strtof(p, &end);
                if (end == p)
                    break;
                p = end;
            }
            struct model_out out;
            model_predict(x, x + 4, x + 8, n >= 12 ? x + 10 : 0, &out);
            for (int q = 0; q < 4; q++)
                printf("%.9g ", (double)out.v[q]);
            for (int q = 0; q < 4; q++)
                printf("%.9g ", (double)out.se[q]);
            printf("%u\n", out.flags);
        } else if (req[0] == 'E') {
            float slope, y = model_erf(strtof(req + 1, NULL), &slope);
            printf("%.9g %.9g\n", (double)y, (double)slope);
        } else if (req[0] == 'C') {
            char *p = req + 1;
            long ch = strtol(p, &p, 10);
            printf("%.9g\n", (double)model_si((uint8_t)ch, strtof(p, NULL)));
        } else if (req[0] == 'I') {
            printf("%s %s %s\n", model_id, model_quantities, model_channel_names);
        } else {
            printf("?\n");
        }
        fflush(stdout);
    }
    return 0;
}
