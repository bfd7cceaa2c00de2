/* xdmf.c — XDMF 3 companion of the HDF5 results file: a Temporal collection
 * with one Uniform grid per output step, all data items pointing into the
 * HDF5 file ("results.h5:/dem/steps/12/x").
 *
 * The file is valid XML after every step: the closing lines are written
 * after each grid and the next step seeks back over them (the file only
 * grows, so nothing stale is left behind). A run that dies mid-way still
 * leaves a file ParaView opens. */
#include "proto.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

struct proto_xdmf {
  FILE *fp;
  char *h5_name;
  long tail; /* offset of the closing lines */
};

static const char XDMF_HEAD[] =
    "<?xml version=\"1.0\" ?>\n"
    "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
    "<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n"
    "  <Domain>\n"
    "    <Grid Name=\"TimeSeries\" GridType=\"Collection\" "
    "CollectionType=\"Temporal\">\n";
static const char XDMF_TAIL[] = "    </Grid>\n  </Domain>\n</Xdmf>\n";

/* Writes text with the five XML special characters escaped (valid in both
 * attribute values and element content). */
static void put_escaped(FILE *fp, const char *s) {
  for (; *s; s++) {
    switch (*s) {
      case '&': fputs("&amp;", fp); break;
      case '<': fputs("&lt;", fp); break;
      case '>': fputs("&gt;", fp); break;
      case '"': fputs("&quot;", fp); break;
      case '\'': fputs("&apos;", fp); break;
      default: fputc(*s, fp);
    }
  }
}

/* Writes the tail and records where it starts; flushes. */
static int write_tail(proto_xdmf *x) {
  x->tail = ftell(x->fp);
  if (x->tail < 0) return -1;
  fputs(XDMF_TAIL, x->fp);
  if (fflush(x->fp) != 0 || ferror(x->fp)) return -1;
  return 0;
}

proto_xdmf *proto_xdmf_open(const char *path, const char *h5_name,
                            proto_err *err) {
  if (!path || !h5_name || !h5_name[0]) {
    proto_fail(err, "%s: XDMF file needs a path and an HDF5 file name",
               path ? path : "(null)");
    return NULL;
  }
  proto_xdmf *x = calloc(1, sizeof *x);
  if (x) x->h5_name = strdup(h5_name);
  if (!x || !x->h5_name) {
    if (x) free(x);
    proto_fail(err, "%s: out of memory", path);
    return NULL;
  }
  x->fp = fopen(path, "w");
  if (!x->fp) {
    proto_fail(err, "%s: cannot create XDMF file", path);
    goto fail;
  }
  fputs(XDMF_HEAD, x->fp);
  if (write_tail(x) < 0) {
    proto_fail(err, "%s: cannot write XDMF file", path);
    goto fail;
  }
  return x;
fail:
  if (x->fp) fclose(x->fp);
  free(x->h5_name);
  free(x);
  return NULL;
}

/* Reads the whole file (NULL if it cannot). */
static char *slurp(FILE *fp, long *len) {
  if (fseek(fp, 0, SEEK_END) != 0 || (*len = ftell(fp)) < 0 || fseek(fp, 0, SEEK_SET) != 0)
    return NULL;
  char *text = malloc((size_t)*len + 1);
  if (text && fread(text, 1, (size_t)*len, fp) != (size_t)*len) {
    free(text);
    return NULL;
  }
  if (text) text[*len] = 0;
  return text;
}

proto_xdmf *proto_xdmf_resume(const char *path, const char *h5_name, double t_keep,
                              proto_err *err) {
  FILE *fp = path ? fopen(path, "r+") : NULL;
  if (!fp) return proto_xdmf_open(path, h5_name, err);
  long len = 0;
  char *text = slurp(fp, &len);
  /* the grids this file describes, in order; the first later than t_keep
   * and everything after it go (the tail is rewritten there) */
  const char *end = text ? strstr(text, XDMF_TAIL) : NULL;
  long cut = end ? (long)(end - text) : -1;
  for (const char *g = text ? strstr(text, "      <Grid Name=") : NULL; g && end && g < end;
       g = strstr(g + 1, "      <Grid Name=")) {
    const char *tv = strstr(g, "<Time Value=\"");
    if (tv && strtod(tv + strlen("<Time Value=\""), NULL) > t_keep) {
      cut = (long)(g - text);
      break;
    }
  }
  free(text);
  proto_xdmf *x = cut >= 0 ? calloc(1, sizeof *x) : NULL;
  if (x) x->h5_name = strdup(h5_name);
  if (!x || !x->h5_name || fseek(fp, cut, SEEK_SET) != 0) {
    if (x) free(x->h5_name);
    free(x);
    fclose(fp);
    proto_fail(err, "%s: not an XDMF file cosim wrote, or unreadable", path);
    return NULL;
  }
  x->fp = fp;
  if (write_tail(x) < 0 || ftruncate(fileno(fp), ftell(fp)) != 0) {
    proto_xdmf_close(x);
    proto_fail(err, "%s: cannot rewrite the XDMF file", path);
    return NULL;
  }
  return x;
}

/* <DataItem Dimensions="rows[ cols]" ...>file.h5:/path</DataItem> */
static void data_item(const proto_xdmf *x, const char *indent, int64_t rows,
                      int64_t cols, int is_int, const char *path) {
  FILE *fp = x->fp;
  fprintf(fp, "%s<DataItem Dimensions=\"%" PRId64, indent, rows);
  if (cols > 0) fprintf(fp, " %" PRId64, cols);
  fprintf(fp, "\" NumberType=\"%s\" Precision=\"%d\" Format=\"HDF\">",
          is_int ? "Int" : "Float", is_int ? 4 : 8);
  put_escaped(fp, x->h5_name);
  fputc(':', fp);
  if (path[0] != '/') fputc('/', fp);
  put_escaped(fp, path);
  fputs("</DataItem>\n", fp);
}

static const char *attr_type(int64_t cols) {
  switch (cols) {
    case 1: return "Scalar";
    case 3: return "Vector";
    case 6: return "Tensor6";
    case 9: return "Tensor";
    default: return "Matrix";
  }
}

static const char *last_element(const char *path) {
  const char *slash = strrchr(path, '/');
  return slash ? slash + 1 : path;
}

static void write_topology(const proto_xdmf *x, proto_xdmf_topology topo,
                           int64_t n_nodes, int64_t n_cells,
                           const char *cells) {
  static const char *const names[] = {"Polyvertex", "Tetrahedron",
                                      "Tetrahedron_10", "Triangle"};
  static const int per_cell[] = {1, 4, 10, 3};
  FILE *fp = x->fp;
  if (topo == PROTO_XDMF_POINTS) {
    /* One vertex per node, connectivity implied. */
    fprintf(fp,
            "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"%"
            PRId64 "\" NodesPerElement=\"1\"/>\n",
            n_nodes);
    return;
  }
  fprintf(fp, "        <Topology TopologyType=\"%s\" NumberOfElements=\"%" PRId64
              "\">\n", names[topo], n_cells);
  data_item(x, "          ", n_cells, per_cell[topo], 1, cells);
  fputs("        </Topology>\n", fp);
}

int proto_xdmf_step(proto_xdmf *x, const char *grid_name, double t,
                    proto_xdmf_topology topo, int64_t n_nodes,
                    const char *geometry, int64_t n_cells, const char *cells,
                    int n_attrs, const char *const *attrs,
                    const int64_t *attr_cols, const int64_t *attr_rows) {
  /* Check everything before writing, so a bad call leaves the file valid. */
  if (!x || !x->fp || !geometry || n_nodes < 0 || n_attrs < 0) return -1;
  if ((int)topo < PROTO_XDMF_POINTS || (int)topo > PROTO_XDMF_TRI3) return -1;
  if (topo != PROTO_XDMF_POINTS && (!cells || n_cells < 0)) return -1;
  if (n_attrs > 0 && (!attrs || !attr_cols || !attr_rows)) return -1;
  for (int i = 0; i < n_attrs; i++)
    if (!attrs[i] || attr_cols[i] < 1 || attr_rows[i] < 0) return -1;

  FILE *fp = x->fp;
  if (fseek(fp, x->tail, SEEK_SET) != 0) return -1;
  fputs("      <Grid Name=\"", fp);
  put_escaped(fp, grid_name ? grid_name : "grid");
  fprintf(fp, "\" GridType=\"Uniform\">\n        <Time Value=\"%.17g\"/>\n", t);
  write_topology(x, topo, n_nodes, n_cells, cells);
  fputs("        <Geometry GeometryType=\"XYZ\">\n", fp);
  data_item(x, "          ", n_nodes, 3, 0, geometry);
  fputs("        </Geometry>\n", fp);
  for (int i = 0; i < n_attrs; i++) {
    /* Node-centred when one row per node, else one row per cell. */
    const char *center = attr_rows[i] == n_nodes ? "Node" : "Cell";
    fputs("        <Attribute Name=\"", fp);
    put_escaped(fp, last_element(attrs[i]));
    fprintf(fp, "\" AttributeType=\"%s\" Center=\"%s\">\n",
            attr_type(attr_cols[i]), center);
    /* Scalars are written as 1-D datasets [rows]. */
    data_item(x, "          ", attr_rows[i], attr_cols[i] == 1 ? 0 : attr_cols[i],
              0, attrs[i]);
    fputs("        </Attribute>\n", fp);
  }
  fputs("      </Grid>\n", fp);
  return write_tail(x);
}

int proto_xdmf_close(proto_xdmf *x) {
  if (!x) return 0;
  int rc = 0;
  if (x->fp) {
    /* The tail is already on disk after every step; just check the flush. */
    if (fflush(x->fp) != 0 || ferror(x->fp)) rc = -1;
    if (fclose(x->fp) != 0) rc = -1;
  }
  free(x->h5_name);
  free(x);
  return rc;
}
