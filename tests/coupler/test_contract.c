/* The coupling contract (coupler/contract.c): the shipped role table binds
 * every step/done row to a coupler field; a row that names no field, an
 * unknown field or one of another shape, a summed request, and a field no
 * row binds each stop the start-up with a message naming it. A newcomer's
 * row (built in this test only: not in the shipped table) binds through
 * the same function. */
#include <string.h>

#include "coupler/runner.h"
#include "cosim_test.h"

#define MAX_ROWS 40

static proto_array_spec rows[MAX_ROWS];
static int nrows;

/* A copy of the shipped table to damage. */
static void copy_table(void) {
  const proto_array_spec *t = proto_role_table(&nrows);
  CHECK(nrows + 1 <= MAX_ROWS, "table of %d rows", nrows);
  memcpy(rows, t, sizeof(proto_array_spec) * (size_t)nrows);
}

static proto_array_spec *row_of(proto_role role, proto_msg_kind msg, const char *name) {
  for (int i = 0; i < nrows; i++)
    if (rows[i].role == role && rows[i].msg == msg && strcmp(rows[i].name, name) == 0)
      return &rows[i];
  CHECK(0, "no row %s", name);
  return &rows[0];
}

static const cpl_binding *binding_of(const cpl_contract *c, proto_role role,
                                     proto_msg_kind msg, const char *name) {
  for (int i = 0; i < c->n; i++)
    if (c->b[i].role == role && c->b[i].msg == msg && strcmp(c->b[i].array, name) == 0)
      return &c->b[i];
  return NULL;
}

static void shipped_table_binds(void) {
  static cpl_contract c;
  proto_err err = {0};
  int n;
  const proto_array_spec *t = proto_role_table(&n);
  OK(cpl_contract_build(&c, t, n, &err));
  /* dem: x, v, nodal_force; fem: nodal_force, rim R c omega v, x, v; block: 2; lug: 6 */
  CHECK(c.n == 18, "18 step/done rows bound, got %d", c.n);
  const cpl_binding *f = binding_of(&c, PROTO_ROLE_DEM, PROTO_MSG_DONE, PROTO_A_NODAL_FORCE);
  CHECK(f && f->field == CPL_F_SURF_FORCE && f->sum, "dem forces are summed into surface.force");
  f = binding_of(&c, PROTO_ROLE_FEM, PROTO_MSG_DONE, PROTO_A_X);
  CHECK(f && f->field == CPL_F_SURF_X && !f->sum, "the fem's x is copied into surface.x");
  f = binding_of(&c, PROTO_ROLE_BLOCK, PROTO_MSG_DONE, PROTO_A_FORCE);
  CHECK(f && f->field == CPL_F_ROAD_FORCE && f->sum, "block forces summed into road.force");
  f = binding_of(&c, PROTO_ROLE_LUG, PROTO_MSG_STEP, PROTO_A_BASE);
  const cpl_binding *g = binding_of(&c, PROTO_ROLE_LUG, PROTO_MSG_DONE, PROTO_A_CELL_FORCE);
  CHECK(f && f->field == CPL_F_LUG_BASE && g && g->field == CPL_F_LUG_CELL_FORCE && !g->sum &&
            c.field[CPL_F_LUG_BASE].per_process && c.field[CPL_F_LUG_BASE].dims[0] == PROTO_DIM_CELLS,
        "a lug's base and cell forces: a row of its cells per process, not summed");
  CHECK(cpl_field_parse("rim.omega") == CPL_F_RIM_OMEGA, "field names parse");
}

static void bad_rows_fail(void) {
  static cpl_contract c;
  proto_err err = {0};
  copy_table();
  row_of(PROTO_ROLE_DEM, PROTO_MSG_STEP, PROTO_A_V)->field = NULL;
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err), "role table row dem/step 'v'");
  CHECK_MSG(err, "names no coupler field");

  copy_table();
  row_of(PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_RIM_C)->field = "rim.centre";
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err), "unknown coupler field 'rim.centre'");
  CHECK_MSG(err, "fem/step 'rim_c'");

  copy_table();
  row_of(PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_RIM_C)->field = "rim.R"; /* [3] vs [3,3] */
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err),
             "does not match the coupler field 'rim.R'");

  copy_table();
  row_of(PROTO_ROLE_BLOCK, PROTO_MSG_STEP, PROTO_A_D_ROAD)->sum = 1;
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err), "only replies (done) can be summed");

  copy_table();
  row_of(PROTO_ROLE_FEM, PROTO_MSG_READY, PROTO_A_SURFACE_X0)->field = "surface.x";
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err), "fem/ready 'surface_x0'");

  copy_table(); /* the block's reply dropped: road.force is filled by nobody */
  proto_array_spec *gone = row_of(PROTO_ROLE_BLOCK, PROTO_MSG_DONE, PROTO_A_FORCE);
  *gone = rows[nrows - 1];
  nrows--;
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err),
             "coupler field 'road.force': no role table row reads or fills it");
}

/* A newcomer's row, written in this test only: a further array a dem
 * returns, bound by the table alone to a coupler field of its shape. A
 * scalar per node ([n]) is refused until such a field exists (a new role
 * with its own field: test_new_role.c). */
static void newcomer_row(void) {
  static cpl_contract c;
  proto_err err = {0};
  copy_table();
  rows[nrows++] = (proto_array_spec){PROTO_ROLE_DEM, PROTO_MSG_DONE, "heat_flux", PROTO_F8, 1,
                                     {PROTO_DIM_NODES}, "W", PROTO_WHEN_SURFACE,
                                     "heat flux into each surface node (toy thermal)",
                                     "surface.force", 1};
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err), "role table row dem/done 'heat_flux'");
  rows[nrows - 1].ndim = 2;
  rows[nrows - 1].dims[1] = 3;
  OK(cpl_contract_build(&c, rows, nrows, &err));
  CHECK(c.n == 19, "the newcomer's row is bound too (%d rows)", c.n);
  const cpl_binding *b = binding_of(&c, PROTO_ROLE_DEM, PROTO_MSG_DONE, "heat_flux");
  CHECK(b && b->sum && b->spec == &rows[nrows - 1], "bound to its own row");
}

/* Index rows (the sparse form, PROTOCOL.md "Sparse exchange") go with the
 * [n, ...] row they index, same field; they are not bindings of their own. */
static void index_rows_bind(void) {
  static cpl_contract c;
  proto_err err = {0};
  copy_table();
  OK(cpl_contract_build(&c, rows, nrows, &err));
  const cpl_binding *b = binding_of(&c, PROTO_ROLE_DEM, PROTO_MSG_DONE, PROTO_A_NODAL_FORCE);
  CHECK(b && b->index && strcmp(b->index->name, PROTO_A_NODAL_FORCE_INDEX) == 0,
        "the dem's nodal_force has its sparse form");
  b = binding_of(&c, PROTO_ROLE_DEM, PROTO_MSG_STEP, PROTO_A_V);
  CHECK(b && b->index && strcmp(b->index->name, PROTO_A_V_INDEX) == 0, "so has the dem's v");
  b = binding_of(&c, PROTO_ROLE_FEM, PROTO_MSG_DONE, PROTO_A_X);
  CHECK(b && !b->index, "the fem's x stays dense");
  CHECK(!binding_of(&c, PROTO_ROLE_DEM, PROTO_MSG_STEP, PROTO_A_X_INDEX), "no binding of its own");
  const proto_array_spec idx = {PROTO_ROLE_DEM, PROTO_MSG_DONE, "nodal_force_index", PROTO_I4, 1,
                                {PROTO_DIM_ROWS}, "-", PROTO_WHEN_INDEX, "test", "surface.force", 0};
  for (int i = 0; i < nrows; i++)
    if (rows[i].when == PROTO_WHEN_INDEX && strcmp(rows[i].name, "nodal_force_index") == 0 &&
        rows[i].role == PROTO_ROLE_DEM)
      rows[i].dtype = PROTO_F8;
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err), "an index row is i4 [k]");
  copy_table();
  rows[nrows] = idx;
  rows[nrows++].field = "surface.x";
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err), "must name the field of its [n, ...] row");
  copy_table();
  rows[nrows] = idx;
  rows[nrows++].name = "heat_index";
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err), "no earlier row of its role and message");
}

int main(void) {
  shipped_table_binds();
  index_rows_bind();
  bad_rows_fail();
  newcomer_row();
  return cosim_test_done("test_contract");
}
