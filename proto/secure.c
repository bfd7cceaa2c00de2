/* secure.c — ZeroMQ CURVE for cosim's sockets (PROTOCOL.md "Security";
 * ZeroMQ RFC 26 CurveZMQ and RFC 27 ZAP): key pairs, the client key file a
 * participant or monitor reads, and the socket options of either side. The
 * coupler's ZAP handler (which client keys it lets in) lives in the
 * coupler. Keys never go on a command line: a 0600 file, named by an
 * environment variable or an option. */
#include "proto.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zmq.h>

#define KEY_FILE_CAP 4096 /* a key file is three short lines of JSON */

static const char *const K_SERVER = "server_public";
static const char *const K_PUBLIC = "public";
static const char *const K_SECRET = "secret";

int proto_curve_keypair(char *public_key, char *secret_key, proto_err *err) {
  if (!zmq_has("curve"))
    return proto_fail(err, "security.curve: this libzmq was built without CURVE");
  if (zmq_curve_keypair(public_key, secret_key) != 0)
    return proto_fail(err, "cannot make a CURVE key pair: %s", zmq_strerror(errno));
  return 0;
}

int proto_curve_write(const char *path, const proto_curve *k, proto_err *err) {
  cJSON *o = cJSON_CreateObject();
  cJSON_AddStringToObject(o, K_SERVER, k->server_public);
  cJSON_AddStringToObject(o, K_PUBLIC, k->public_key);
  cJSON_AddStringToObject(o, K_SECRET, k->secret_key);
  char *text = cJSON_Print(o);
  cJSON_Delete(o);
  if (!text) return proto_fail(err, "%s: out of memory", path);
  /* O_EXCL: never write a secret into a file someone else prepared */
  int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  int rc = 0;
  if (fd < 0) {
    rc = proto_fail(err, "cannot create key file %s: %s", path, strerror(errno));
  } else {
    size_t len = strlen(text);
    if (write(fd, text, len) != (ssize_t)len || write(fd, "\n", 1) != 1)
      rc = proto_fail(err, "cannot write key file %s: %s", path, strerror(errno));
    if (close(fd) != 0 && rc == 0)
      rc = proto_fail(err, "cannot write key file %s: %s", path, strerror(errno));
  }
  free(text);
  return rc;
}

static int get_key(const cJSON *o, const char *name, char *out, const char *path,
                   proto_err *err) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, name);
  if (!cJSON_IsString(v) || strlen(v->valuestring) != PROTO_KEY_LEN - 1)
    return proto_fail(err, "%s: '%s' must be a %d-character Z85 key", path, name,
                      PROTO_KEY_LEN - 1);
  uint8_t raw[32];
  if (!zmq_z85_decode(raw, v->valuestring))
    return proto_fail(err, "%s: '%s' is not a Z85 key", path, name);
  memcpy(out, v->valuestring, PROTO_KEY_LEN);
  return 0;
}

int proto_curve_read(const char *path, proto_curve *k, proto_err *err) {
  int fd = open(path, O_RDONLY | O_CLOEXEC);
  struct stat st;
  if (fd < 0 || fstat(fd, &st) != 0) {
    int e = errno;
    if (fd >= 0) close(fd);
    return proto_fail(err, "cannot read key file %s: %s", path, strerror(e));
  }
  if (st.st_mode & 077) {
    close(fd);
    return proto_fail(err, "key file %s may be read by others (mode %03o): it "
                      "must be 0600", path, (unsigned)(st.st_mode & 0777));
  }
  char text[KEY_FILE_CAP];
  ssize_t n = read(fd, text, sizeof text - 1);
  close(fd);
  if (n < 0) return proto_fail(err, "cannot read key file %s: %s", path, strerror(errno));
  text[n] = 0;
  cJSON *o = proto_json_parse(text, path, err);
  if (!o) return -1;
  int rc = get_key(o, K_SERVER, k->server_public, path, err) < 0 ||
                   get_key(o, K_PUBLIC, k->public_key, path, err) < 0 ||
                   get_key(o, K_SECRET, k->secret_key, path, err) < 0
               ? -1
               : 0;
  cJSON_Delete(o);
  return rc;
}

static int opt(void *s, int option, const void *value, size_t len, const char *what,
               proto_err *err) {
  if (zmq_setsockopt(s, option, value, len) == 0) return 0;
  return proto_fail(err, "cannot set %s: %s", what, zmq_strerror(errno));
}

int proto_curve_client(void *socket, const proto_curve *k, proto_err *err) {
  const size_t n = PROTO_KEY_LEN; /* Z85 form with its NUL */
  return opt(socket, ZMQ_CURVE_SERVERKEY, k->server_public, n, "CURVE server key", err) < 0 ||
                 opt(socket, ZMQ_CURVE_PUBLICKEY, k->public_key, n, "CURVE public key", err) < 0 ||
                 opt(socket, ZMQ_CURVE_SECRETKEY, k->secret_key, n, "CURVE secret key", err) < 0
             ? -1
             : 0;
}

int proto_curve_server(void *socket, const char *secret_key, const char *domain,
                       proto_err *err) {
  int on = 1;
  return opt(socket, ZMQ_CURVE_SERVER, &on, sizeof on, "CURVE server", err) < 0 ||
                 opt(socket, ZMQ_CURVE_SECRETKEY, secret_key, PROTO_KEY_LEN,
                     "CURVE secret key", err) < 0 ||
                 opt(socket, ZMQ_ZAP_DOMAIN, domain, strlen(domain), "ZAP domain", err) < 0
             ? -1
             : 0;
}
