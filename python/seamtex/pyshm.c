/* python/seamtex/pyshm.c - Client(..., shm=..., shm_bytes=...): shared-memory sampling
 * (PROTOCOL.md 4.12) on a unix: connection, and the Client.shm_status attribute.
 *
 * Owns: the policy ("auto", the default: a region when the connection and the daemon allow it,
 * else the socket with the reason kept; True: a region or an exception; False: never), the
 * region's size
 * argument, the status dict. Does not own: the region, the ring, SHM_ATTACH (libseamtex,
 * stc_shm_attach); sampling through the region needs nothing here: stc_sample uses it by itself.
 */
#include "pyseamtex.h"

#include <string.h>

/* shm_o -> *policy: 0 off, 1 on, 2 auto (also when shm_o is NULL: not given); -1 with
 * ValueError set. */
static int shm_policy(PyObject *shm_o, int *policy)
{
    if (!shm_o) {
        *policy = 2;
        return 0;
    }
    if (shm_o == Py_False || shm_o == Py_None) {
        *policy = 0;
        return 0;
    }
    if (shm_o == Py_True) {
        *policy = 1;
        return 0;
    }
    if (PyUnicode_Check(shm_o) && PyUnicode_CompareWithASCIIString(shm_o, "auto") == 0) {
        *policy = 2;
        return 0;
    }
    PyErr_SetString(PyExc_ValueError, "shm must be False, True or 'auto'");
    return -1;
}

int st_py_shm_open(st_py_client *self, PyObject *shm_o, Py_ssize_t bytes)
{
    int policy;
    self->shm_bytes = 0;
    self->shm_why[0] = 0;
    if (shm_policy(shm_o, &policy) < 0)
        return -1;
    if (bytes < 1) {
        PyErr_SetString(PyExc_ValueError, "shm_bytes must be at least 1");
        return -1;
    }
    if (policy == 0) {
        snprintf(self->shm_why, sizeof self->shm_why, "not asked for (shm=False)");
        return 0;
    }
    if (policy == 2 && strncmp(self->host, "unix:", 5) != 0) {
        snprintf(self->shm_why, sizeof self->shm_why, "not a unix: address");
        return 0;
    }
    int rc;
    Py_BEGIN_ALLOW_THREADS
    rc = stc_shm_attach(self->conn, (size_t)bytes);
    Py_END_ALLOW_THREADS
    if (rc == 0) {
        self->shm_bytes = (size_t)bytes;
        return 0;
    }
    /* asked for, the connection broke, or Ctrl-C (the interrupt hook: its exception) */
    if (policy == 1 || stc_error(self->conn) || rc == STC_EINTERRUPTED) {
        st_py_client_fail(self, rc);
        return -1;
    }
    snprintf(self->shm_why, sizeof self->shm_why, "%s", stc_errmsg(self->conn));
    return 0;
}

PyObject *st_py_shm_status(st_py_client *self, void *closure)
{
    (void)closure;
    /* no lock (it used to wait behind another thread's call): the counts as of the end of
     * the last call (st_py_client_leave keeps them), the region fixed at connect */
    if (st_py_client_usable(self) < 0)
        return NULL;
    uint64_t via_shm = self->via_shm, via_sock = self->via_sock;
    PyObject *why = self->shm_bytes ? Py_None : PyUnicode_FromString(self->shm_why);
    if (!why)
        return NULL;
    if (why == Py_None)
        Py_INCREF(why);
    return Py_BuildValue("{s:O,s:K,s:K,s:K,s:N}", "attached", self->shm_bytes ? Py_True
                         : Py_False, "bytes", (unsigned long long)self->shm_bytes, "via_shm",
                         (unsigned long long)via_shm, "via_socket", (unsigned long long)via_sock,
                         "reason", why);
}
