/* punch_table — K/(2E*a) of a flat punch on a bonded film vs a/h, with the
 * two limits, for the picture in bench/results/green_springs.md. */
#include <math.h>
#include <stdio.h>

#include "green/green.h"

int main(void) {
  proto_err err;
  printf("# a_over_h phi nu=0.5  halfspace thin_film(3pi/64 (a/h)^3)  phi nu=0.45\n");
  for (int i = 0; i <= 24; i++) {
    double lam = 1e-2 * pow(10, 3.6 * i / 24), phi, phi2;
    if (grn_punch_solve(lam, 0.5, 0, &phi, &err) || grn_punch_solve(lam, 0.45, 0, &phi2, &err)) {
      fprintf(stderr, "%s\n", err.msg);
      return 1;
    }
    printf("%.6e %.6e 1 %.6e %.6e\n", lam, phi, 3 * M_PI / 64 * lam * lam * lam, phi2);
  }
  return 0;
}
