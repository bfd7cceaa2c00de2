/* material.c — the viscoelastic layer's E(f), eta(f) table. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "green/green.h"

void grn_material_default(grn_material *m) {
  /* Seed 002 appendix B, top layer: 25 MPa at 0 Hz rising to a constant
   * 50 MPa at high frequency; loss factor 0.005 at 10 Hz to 0.55 at 50 kHz.
   * The intermediate (Continental tyre) points are not printed in the thesis:
   * here E and log(eta) rise smoothly in log f between the stated ends. */
  static const double f[] = {0, 10, 100, 1e3, 1.6e3, 5e3, 1e4, 2e4, 5e4};
  static const double E[] = {25e6, 25e6, 26e6, 30e6, 32e6, 38e6, 42e6, 46e6, 50e6};
  static const double eta[] = {0.005, 0.005, 0.014, 0.045, 0.06, 0.12, 0.19, 0.3, 0.55};
  memset(m, 0, sizeof *m);
  m->n = (int)(sizeof f / sizeof f[0]);
  memcpy(m->f, f, sizeof f);
  memcpy(m->E, E, sizeof E);
  memcpy(m->eta, eta, sizeof eta);
  m->nu = 0.499;
  m->rho = 1300;
}

int grn_material_check(const grn_material *m, proto_err *err) {
  if (m->n < 1 || m->n > GRN_TABLE_MAX)
    return proto_fail(err, "loss-factor table: %d rows (need 1..%d)", m->n, GRN_TABLE_MAX);
  for (int i = 0; i < m->n; i++) {
    if (!isfinite(m->f[i]) || m->f[i] < 0)
      return proto_fail(err, "loss-factor table: f[%d] = %g Hz: must be >= 0", i, m->f[i]);
    if (i > 0 && !(m->f[i] > m->f[i - 1]))
      return proto_fail(err, "loss-factor table out of order: f[%d] = %g Hz after "
                             "f[%d] = %g Hz (frequencies must increase)",
                        i, m->f[i], i - 1, m->f[i - 1]);
    if (!(m->E[i] > 0) || !isfinite(m->E[i]))
      return proto_fail(err, "loss-factor table: E[%d] = %g Pa: must be > 0", i, m->E[i]);
    if (!(m->eta[i] >= 0 && m->eta[i] < 10))
      return proto_fail(err, "loss-factor table: eta[%d] = %g: must be in [0, 10)", i, m->eta[i]);
  }
  if (!(m->nu >= 0 && m->nu <= 0.5))
    return proto_fail(err, "nu = %g: must be in [0, 0.5]", m->nu);
  if (!(m->rho > 0) || !isfinite(m->rho))
    return proto_fail(err, "rho = %g: must be > 0", m->rho);
  return 0;
}

void grn_material_at(const grn_material *m, double f, double *E, double *eta) {
  if (f <= m->f[0] || m->n == 1) {
    *E = m->E[0];
    *eta = m->eta[0];
    return;
  }
  if (f >= m->f[m->n - 1]) {
    *E = m->E[m->n - 1];
    *eta = m->eta[m->n - 1];
    return;
  }
  int i = 1;
  while (m->f[i] < f)
    i++;
  /* linear in log f when both ends are > 0, else linear in f */
  double t = m->f[i - 1] > 0 ? log(f / m->f[i - 1]) / log(m->f[i] / m->f[i - 1])
                             : (f - m->f[i - 1]) / (m->f[i] - m->f[i - 1]);
  *E = m->E[i - 1] + t * (m->E[i] - m->E[i - 1]);
  if (m->eta[i - 1] > 0 && m->eta[i] > 0)
    *eta = m->eta[i - 1] * pow(m->eta[i] / m->eta[i - 1], t);
  else
    *eta = m->eta[i - 1] + t * (m->eta[i] - m->eta[i - 1]);
}

int grn_material_load(grn_material *m, const char *path, proto_err *err) {
  FILE *fp = fopen(path, "r");
  if (!fp)
    return proto_fail(err, "%s: %s", path, strerror(errno));
  char line[512];
  int n = 0, lineno = 0;
  while (fgets(line, sizeof line, fp)) {
    lineno++;
    char *s = line;
    while (*s == ' ' || *s == '\t') s++;
    if (*s == '#' || *s == '\n' || *s == '\0' || *s == '\r')
      continue;
    double f, E, eta;
    if (sscanf(s, "%lf %lf %lf", &f, &E, &eta) != 3) {
      fclose(fp);
      return proto_fail(err, "%s:%d: expected three numbers 'f E eta'", path, lineno);
    }
    if (n >= GRN_TABLE_MAX) {
      fclose(fp);
      return proto_fail(err, "%s:%d: more than %d rows", path, lineno, GRN_TABLE_MAX);
    }
    m->f[n] = f;
    m->E[n] = E;
    m->eta[n] = eta;
    n++;
  }
  fclose(fp);
  m->n = n;
  if (grn_material_check(m, err))
    return proto_wrap(err, "%s", path);
  return 0;
}
