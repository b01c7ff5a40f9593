/* python/seamtex/pyclient.c - seamtex._seamtex.Client: one libseamtex connection as a Python
 * object (connect, close, context manager, ping, ls, info, upload, delete, stats, compress
 * jobs, fetch). Sampling is in pysample.c.
 *
 * Owns: turning Python arguments into stc_* arguments and results into dicts, the Client's
 * lock (one thread on the connection at a time, the library's rule), releasing the GIL around
 * every call that waits on the network, progress callbacks (called with the GIL taken again;
 * an exception in one aborts the transfer and is re-raised), the interrupt hook (Ctrl-C stops
 * a call that waits, even with timeout=None: st_py_interrupt).
 * Does not own: the protocol, retries or resumption policy (libseamtex), numpy.
 */
#include "pyseamtex.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <pthread.h>
#include <time.h>
#include <unistd.h>

#include "proto.h"

/* ---- lock and errors --------------------------------------------------------------------------- */

/* Takes the lock, waiting with the GIL released; raises StateError when this thread holds it
 * already (a progress callback of a call on this Client). */
static int lock_take(st_py_client *self)
{
    unsigned long me = PyThread_get_thread_ident();
    if (!PyThread_acquire_lock(self->lock, NOWAIT_LOCK)) {
        if (self->owner == me) {  /* only this thread can have stored its own ident */
            st_py_raise(STC_ESTATE, "this Client is in a call on this thread already (a "
                        "progress callback cannot use its own Client)");
            return -1;
        }
        Py_BEGIN_ALLOW_THREADS
        PyThread_acquire_lock(self->lock, WAIT_LOCK);
        Py_END_ALLOW_THREADS
    }
    self->owner = me;
    return 0;
}

volatile unsigned long st_py_fork_gen;

static void on_fork_child(void)
{
    st_py_fork_gen++;
}

int st_py_fork_watch(void)
{
    return pthread_atfork(NULL, NULL, on_fork_child) == 0 ? 0 : -1;
}

/* 1 in a child after fork: the connection is the parent's (its socket, region and request
 * ids are shared; using it there crossed replies: the parent's Client broke with
 * ProtocolError, and through shared memory results came back wrong). */
static int forked(const st_py_client *self)
{
    return self->conn && self->fork_gen != st_py_fork_gen;
}

/* In such a child: drops this process's copy of the connection (stc_close leaves the parent's
 * alone) and gives the Client a fresh lock (a parent's thread may have held the old one at the
 * fork; no thread here waits on it). */
static void forget_parents(st_py_client *self)
{
    PyThread_type_lock fresh = PyThread_allocate_lock();
    stc_close(self->conn);
    self->conn = NULL;
    free(self->scratch);
    self->scratch = NULL;
    self->scratch_cap = 0;
    self->shm_bytes = 0;
    if (fresh) {
        PyThread_free_lock(self->lock);
        self->lock = fresh;
    }
    self->owner = 0;
}

/* The checks before the lock, shared by st_py_client_enter and st_py_client_usable. */
static int usable_before_lock(st_py_client *self)
{
    if (!self->lock) {
        st_py_raise_closed("the Client is not initialised");
        return -1;
    }
    if (forked(self)) {
        char m[200];
        snprintf(m, sizeof m, "this Client was connected by process %ld: after fork a child "
                 "must open its own Client (close() here is fine)", self->pid);
        st_py_raise(STC_ESTATE, m);
        return -1;
    }
    return 0;
}

int st_py_client_usable(st_py_client *self)
{
    if (usable_before_lock(self) < 0)
        return -1;
    if (!self->conn) {
        st_py_raise_closed("the Client is closed");
        return -1;
    }
    return 0;
}

int st_py_client_enter(st_py_client *self)
{
    if (usable_before_lock(self) < 0)
        return -1;
    if (lock_take(self) < 0)
        return -1;
    if (!self->conn) {
        self->owner = 0;
        PyThread_release_lock(self->lock);
        st_py_raise_closed("the Client is closed");
        return -1;
    }
    return 0;
}

/* Hands the exception a signal handler raised during the call to Python (1), else 0. */
static int interrupt_reraise(st_py_client *self)
{
    if (!self->intr_type)
        return 0;
    PyErr_Restore(self->intr_type, self->intr_value, self->intr_tb);
    self->intr_type = self->intr_value = self->intr_tb = NULL;
    return 1;
}

unsigned long st_py_main_thread;

int st_py_interrupt(void *user)
{
    st_py_client *self = user;
    if (self->intr_type)                /* said stop already in this call */
        return 1;
    if (PyThread_get_thread_ident() != st_py_main_thread)
        return 0;                       /* handlers run on the main thread only */
    PyGILState_STATE g = PyGILState_Ensure();
    int stop = PyErr_CheckSignals() < 0;
    if (stop)
        PyErr_Fetch(&self->intr_type, &self->intr_value, &self->intr_tb);
    PyGILState_Release(g);
    return stop;
}

void st_py_client_leave(st_py_client *self)
{
    Py_CLEAR(self->intr_type);          /* none left but one a raised exception overtook */
    Py_CLEAR(self->intr_value);
    Py_CLEAR(self->intr_tb);
    stc_shm_counts(self->conn, &self->via_shm, &self->via_sock);   /* NULL conn: 0, 0 */
    self->owner = 0;
    PyThread_release_lock(self->lock);
}

int st_py_uint_arg(PyObject *o, const char *what, unsigned long max, unsigned *out)
{
    if (!o || o == Py_None)
        return 0;
    PyObject *ix = PyNumber_Index(o);
    if (!ix) {
        PyErr_Format(PyExc_TypeError, "%s must be an integer, not %.80s", what,
                     Py_TYPE(o)->tp_name);
        return -1;
    }
    int over = 0;
    long long v = PyLong_AsLongLongAndOverflow(ix, &over);
    Py_DECREF(ix);
    if (v == -1 && PyErr_Occurred())
        return -1;
    if (over || v < 0 || (unsigned long long)v > max) {
        PyErr_Format(PyExc_ValueError, "%s is 0..%lu, not %R", what, max, o);
        return -1;
    }
    *out = (unsigned)v;
    return 0;
}

double st_py_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

void *st_py_client_scratch(st_py_client *self, size_t bytes)
{
    if (bytes > self->scratch_cap) {
        void *p = realloc(self->scratch, bytes);
        if (!p)
            return NULL;
        self->scratch = p;
        self->scratch_cap = bytes;
    }
    return self->scratch;
}

PyObject *st_py_client_fail(st_py_client *self, int rc)
{
    if (interrupt_reraise(self))
        return NULL;
    return st_py_raise(rc, self->conn ? stc_errmsg(self->conn) : "");
}

/* ---- progress callbacks ------------------------------------------------------------------------ */

typedef struct progress {
    PyObject *cb;                       /* callable(done, total) or NULL */
    PyObject *etype, *evalue, *etb;     /* the exception that stopped the transfer */
} progress;

/* Runs on the thread that released the GIL: takes it back for the call. A callback that
 * raises, or a pending signal (Ctrl-C on the main thread), stops the transfer. */
static int progress_fn(void *user, uint64_t done, uint64_t total)
{
    progress *p = user;
    PyGILState_STATE g = PyGILState_Ensure();
    int stop = 0;
    if (p->cb) {
        PyObject *r = PyObject_CallFunction(p->cb, "KK", (unsigned long long)done,
                                            (unsigned long long)total);
        if (r)
            Py_DECREF(r);
        else
            stop = 1;
    }
    if (!stop && PyErr_CheckSignals() < 0)
        stop = 1;
    if (stop)
        PyErr_Fetch(&p->etype, &p->evalue, &p->etb);
    PyGILState_Release(g);
    return stop;
}

/* After the call: re-raises what stopped it (returns 1), else 0. */
static int progress_reraise(progress *p)
{
    if (!p->etype)
        return 0;
    PyErr_Restore(p->etype, p->evalue, p->etb);
    p->etype = p->evalue = p->etb = NULL;
    return 1;
}

static int progress_arg(PyObject *cb, progress *p)
{
    memset(p, 0, sizeof *p);
    if (cb && cb != Py_None) {
        if (!PyCallable_Check(cb)) {
            PyErr_SetString(PyExc_TypeError, "progress must be a callable(done, total)");
            return -1;
        }
        p->cb = cb;
    }
    return 0;
}

/* ---- lifetime -------------------------------------------------------------------------------- */

static int ms_of(double secs)
{
    if (!(secs > 0))
        return 0;
    return secs * 1000.0 > 2e9 ? 2000000000 : (int)ceil(secs * 1000.0);
}

static int client_connect(st_py_client *self, const char *host, unsigned port,
                          const char *token, double timeout, const char *cname,
                          PyObject *shm_o, Py_ssize_t shm_bytes);

static int client_init(st_py_client *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"host", "port", "token", "timeout", "numpy", "client_name", "shm",
                             "shm_bytes", NULL};
    const char *host = "127.0.0.1", *token = NULL, *cname = "seamtex-python";
    unsigned port = 7450;
    PyObject *port_o = NULL, *timeout_o = NULL, *numpy_o = Py_None;
    PyObject *shm_o = NULL;   /* NULL: "auto" */
    Py_ssize_t shm_bytes = ST_PY_SHM_DEFAULT;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "|sOzO$OsOn:Client", kwlist, &host, &port_o,
                                     &token, &timeout_o, &numpy_o, &cname, &shm_o, &shm_bytes))
        return -1;
    if (st_py_uint_arg(port_o, "port", 65535, &port) < 0)
        return -1;
    double timeout = 10.0;
    if (timeout_o && timeout_o != Py_None) {
        timeout = PyFloat_AsDouble(timeout_o);
        if (timeout == -1.0 && PyErr_Occurred())
            return -1;
        if (!(timeout > 0)) {
            PyErr_SetString(PyExc_ValueError, "timeout must be > 0 seconds, or None for none");
            return -1;
        }
    } else if (timeout_o == Py_None) {
        timeout = 0;
    }
    self->numpy = numpy_o == Py_None ? -1 : PyObject_IsTrue(numpy_o);
    if (self->numpy < -1 || (numpy_o != Py_None && self->numpy < 0))
        return -1;
    if (!self->lock && !(self->lock = PyThread_allocate_lock())) {
        PyErr_NoMemory();
        return -1;
    }
    if (forked(self))             /* __init__ again in a child after fork */
        forget_parents(self);
    /* The lock for the whole (re)connect: __init__ called again on an open Client waits for
     * another thread's call on the old connection to finish before closing it (it used to
     * close it under that call), and no call starts on the new one before it is set up. */
    if (lock_take(self) < 0)
        return -1;
    int rc = client_connect(self, host, port, token, timeout, cname, shm_o, shm_bytes);
    st_py_client_leave(self);
    return rc;
}

/* client_init's connect, the lock held: closes the old connection (__init__ called again),
 * connects, says HELLO, attaches shared memory as asked. */
static int client_connect(st_py_client *self, const char *host, unsigned port,
                          const char *token, double timeout, const char *cname,
                          PyObject *shm_o, Py_ssize_t shm_bytes)
{
    if (self->conn) {             /* __init__ called again: start over */
        stc_conn *old = self->conn;
        self->conn = NULL;
        Py_BEGIN_ALLOW_THREADS
        stc_close(old);
        Py_END_ALLOW_THREADS
    }
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.connect_timeout_ms = timeout > 0 ? ms_of(timeout) : -1;
    o.request_timeout_ms = ms_of(timeout);
    o.token = token;
    o.client_name = cname;
    o.interrupt = st_py_interrupt;      /* Ctrl-C: connect, HELLO, then every call */
    o.interrupt_user = self;
    o.interrupt_every_ms = ST_PY_INTERRUPT_MS;
    int err = 0;
    char msg[512] = "";
    stc_conn *c;
    Py_BEGIN_ALLOW_THREADS
    c = stc_connect_opts(host, port, &o, &err, msg, sizeof msg);
    Py_END_ALLOW_THREADS
    if (!c) {
        if (!interrupt_reraise(self))
            st_py_raise(err, msg);
        return -1;
    }
    self->hello = *stc_server_info(c);
    self->via_shm = self->via_sock = 0;
    self->conn = c;
    self->pid = (long)getpid();
    self->fork_gen = st_py_fork_gen;
    self->timeout = timeout;
    snprintf(self->host, sizeof self->host, "%s", host);
    self->port = port;
    if (st_py_shm_open(self, shm_o, shm_bytes) < 0) {
        self->conn = NULL;
        Py_BEGIN_ALLOW_THREADS
        stc_close(c);
        Py_END_ALLOW_THREADS
        return -1;
    }
    return 0;
}

static void client_dealloc(st_py_client *self)
{
    Py_CLEAR(self->intr_type);
    Py_CLEAR(self->intr_value);
    Py_CLEAR(self->intr_tb);
    stc_close(self->conn);
    free(self->scratch);
    if (self->lock)
        PyThread_free_lock(self->lock);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *client_close(st_py_client *self, PyObject *unused)
{
    (void)unused;
    if (!self->lock || !self->conn)
        Py_RETURN_NONE;
    if (forked(self)) {
        forget_parents(self);
        Py_RETURN_NONE;
    }
    if (st_py_client_enter(self) < 0) {
        /* closed meanwhile by another thread: fine. Called from a progress callback of a
         * call on this Client: StateError (closing under that call is not possible; it used
         * to return None with the Client still open). */
        if (!PyErr_ExceptionMatches(st_py_closed_error()))
            return NULL;
        PyErr_Clear();
        Py_RETURN_NONE;
    }
    stc_conn *c = self->conn;
    self->conn = NULL;
    free(self->scratch);
    self->scratch = NULL;
    self->scratch_cap = 0;
    Py_BEGIN_ALLOW_THREADS
    stc_close(c);
    Py_END_ALLOW_THREADS
    st_py_client_leave(self);
    Py_RETURN_NONE;
}

static PyObject *client_enter_ctx(st_py_client *self, PyObject *unused)
{
    (void)unused;
    if (!self->conn) {
        st_py_raise_closed("the Client is closed");
        return NULL;
    }
    Py_INCREF(self);
    return (PyObject *)self;
}

static PyObject *client_exit_ctx(st_py_client *self, PyObject *args)
{
    (void)args;
    PyObject *r = client_close(self, NULL);
    Py_XDECREF(r);
    if (!r)
        return NULL;
    Py_RETURN_FALSE;
}

static PyObject *client_repr(st_py_client *self)
{
    if (strncmp(self->host, "unix:", 5) == 0)   /* a Unix socket: no port */
        return PyUnicode_FromFormat("<seamtex.Client %s%s>", self->host,
                                    self->conn ? "" : " closed");
    return PyUnicode_FromFormat("<seamtex.Client %s:%u%s>", self->host, self->port,
                                self->conn ? "" : " closed");
}

/* ---- small calls ------------------------------------------------------------------------------- */

/* Runs `call` (an expression using c) with the lock held and the GIL released; on failure
 * raises and returns NULL from the method. */
#define CALL_OR_FAIL(self, rc, call)                                                   \
    do {                                                                               \
        if (st_py_client_enter(self) < 0)                                              \
            return NULL;                                                               \
        stc_conn *c = (self)->conn;                                                    \
        Py_BEGIN_ALLOW_THREADS                                                         \
        rc = (call);                                                                   \
        Py_END_ALLOW_THREADS                                                           \
        if (rc) {                                                                      \
            st_py_client_fail(self, rc);                                               \
            st_py_client_leave(self);                                                  \
            return NULL;                                                               \
        }                                                                              \
    } while (0)

static PyObject *client_ping(st_py_client *self, PyObject *unused)
{
    (void)unused;
    int rc;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    CALL_OR_FAIL(self, rc, stc_ping(c));
    st_py_client_leave(self);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    return PyFloat_FromDouble((double)(t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) * 1e-9);
}

static PyObject *client_ls(st_py_client *self, PyObject *unused)
{
    (void)unused;
    const stc_set_entry *sets = NULL;
    size_t n = 0;
    int rc;
    CALL_OR_FAIL(self, rc, stc_list(c, &sets, &n));
    PyObject *l = PyList_New((Py_ssize_t)n);
    for (size_t i = 0; l && i < n; i++) {
        const char *kind = stp_kind_name(sets[i].kind), *dt = stp_dtype_name(sets[i].dtype);
        PyObject *d = Py_BuildValue("{s:s,s:s,s:I,s:s,s:I,s:K}", "name", sets[i].name,
                                    "kind", kind ? kind : "?", "nchan", sets[i].nchan,
                                    "dtype", dt ? dt : "?", "nfaces", (unsigned)sets[i].nfaces,
                                    "memory", (unsigned long long)sets[i].memory);
        if (!d)
            Py_CLEAR(l);
        else
            PyList_SET_ITEM(l, (Py_ssize_t)i, d);
    }
    st_py_client_leave(self);
    return l;
}

static PyObject *face_dict(const stc_face *f, uint32_t id)
{
    return Py_BuildValue("{s:I,s:I,s:I,s:[iiii],s:[BBBB],s:B,s:B}", "id", (unsigned)id,
                         "w", (unsigned)f->w, "h", (unsigned)f->h, "adjface",
                         f->adjface[0], f->adjface[1], f->adjface[2], f->adjface[3], "adjedge",
                         f->adjedge[0], f->adjedge[1], f->adjedge[2], f->adjedge[3], "flags",
                         f->flags, "nlevels", f->nlevels);
}

static PyObject *client_info(st_py_client *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"name", "faces", NULL};
    const char *name;
    PyObject *faces = Py_None;
    unsigned first = 0, count = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s|O:info", kwlist, &name, &faces))
        return NULL;
    if (faces != Py_None) {
        if (PyIndex_Check(faces)) {
            if (st_py_uint_arg(faces, "faces", UINT32_MAX, &count) < 0)
                return NULL;
        } else if (!PyTuple_Check(faces) || PyTuple_GET_SIZE(faces) != 2) {
            PyErr_SetString(PyExc_TypeError, "faces must be a count or a (first, count) tuple");
            return NULL;
        } else if (st_py_uint_arg(PyTuple_GET_ITEM(faces, 0), "faces' first", UINT32_MAX,
                                  &first) < 0 ||
                   st_py_uint_arg(PyTuple_GET_ITEM(faces, 1), "faces' count", UINT32_MAX,
                                  &count) < 0) {
            return NULL;
        }
    }
    stc_info in;
    int rc;
    CALL_OR_FAIL(self, rc, stc_info_get(c, name, first, count, &in));
    const char *kind = stp_kind_name(in.kind), *dt = stp_dtype_name(in.dtype);
    PyObject *fl = PyList_New(in.faces ? in.nrec : 0);
    for (uint32_t i = 0; fl && in.faces && i < in.nrec; i++) {
        PyObject *f = face_dict(&in.faces[i], in.face_first + i);
        if (!f)
            Py_CLEAR(fl);
        else
            PyList_SET_ITEM(fl, i, f);
    }
    st_py_client_leave(self);
    if (!fl)
        return NULL;
    PyObject *d = Py_BuildValue(
        "{s:s,s:I,s:I,s:s,s:s,s:I,s:O,s:I,s:I,s:I,s:I,s:i,s:K,s:K,s:I,s:I,s:I,s:I,s:I,s:I,s:I,s:I,"
        "s:I,s:I,s:N}",
        "name", name, "nfaces", (unsigned)in.nfaces, "nchan", in.nchan, "dtype", dt ? dt : "?",
        "kind", kind ? kind : "?", "colorspace", in.colorspace,
        "premultiplied", in.premultiplied ? Py_True : Py_False, "border_u", in.border_u,
        "border_v", in.border_v, "meshtype", in.meshtype, "edgefilter", in.edgefilter,
        "alpha_chan", in.alpha_chan,
        "memory", (unsigned long long)in.memory, "texel_bytes", (unsigned long long)in.texel_bytes,
        "min_w", (unsigned)in.min_w, "max_w", (unsigned)in.max_w, "min_h", (unsigned)in.min_h,
        "max_h", (unsigned)in.max_h, "nconstant", (unsigned)in.nconstant,
        "nsubfaces", (unsigned)in.nsubfaces, "boundary_edges", (unsigned)in.boundary_edges,
        "irregular_corners", (unsigned)in.irregular_corners,
        "max_valence", (unsigned)in.max_valence, "nmeta", (unsigned)in.nmeta, "faces", fl);
    return d;
}

static PyObject *client_delete(st_py_client *self, PyObject *args)
{
    const char *name;
    int rc;
    if (!PyArg_ParseTuple(args, "s:delete", &name))
        return NULL;
    CALL_OR_FAIL(self, rc, stc_delete(c, name));
    st_py_client_leave(self);
    Py_RETURN_NONE;
}

static PyObject *client_stats(st_py_client *self, PyObject *unused)
{
    (void)unused;
    const stc_stat *st = NULL;
    size_t n = 0;
    int rc;
    CALL_OR_FAIL(self, rc, stc_stats(c, &st, &n));
    PyObject *d = PyDict_New();
    for (size_t i = 0; d && i < n; i++) {
        PyObject *v = st[i].is_float ? PyFloat_FromDouble(st[i].f)
                                     : PyLong_FromUnsignedLongLong(st[i].u);
        if (!v || PyDict_SetItemString(d, st[i].key, v) < 0)
            Py_CLEAR(d);
        Py_XDECREF(v);
    }
    st_py_client_leave(self);
    return d;
}

/* ---- uploads ----------------------------------------------------------------------------------- */

/* **options -> "k=v k=v" (the server's import option string). */
static int options_string(PyObject *kw, char *out, size_t cap)
{
    size_t len = 0;
    Py_ssize_t pos = 0;
    PyObject *k, *v;
    out[0] = 0;
    while (kw && PyDict_Next(kw, &pos, &k, &v)) {
        PyObject *s = PyBool_Check(v) ? PyUnicode_FromString(v == Py_True ? "1" : "0")
                                      : PyObject_Str(v);
        if (!s)
            return -1;
        Py_ssize_t kn = 0, vn = 0;
        const char *ks = PyUnicode_AsUTF8AndSize(k, &kn), *vs = PyUnicode_AsUTF8AndSize(s, &vn);
        if (!ks || !vs) {
            Py_DECREF(s);
            return -1;
        }
        /* a NUL would cut the C string short: texture="a\0b" used to send texture=a */
        int bad = !vn || !kn || (size_t)vn != strlen(vs) || (size_t)kn != strlen(ks) ||
                  strchr(ks, '=');
        for (Py_ssize_t i = 0; i < vn && !bad; i++)
            bad = (unsigned char)vs[i] <= ' ' || vs[i] == '=' || vs[i] == 0x7f;
        for (Py_ssize_t i = 0; i < kn && !bad; i++)
            bad = (unsigned char)ks[i] <= ' ' || ks[i] == 0x7f;
        if (bad) {
            PyErr_Format(PyExc_ValueError, "upload option %R=%R: a name and a value must be "
                         "non-empty and hold no blank, control character or '='", k, v);
            Py_DECREF(s);
            return -1;
        }
        int w = snprintf(out + len, cap - len, "%s%s=%s", len ? " " : "", ks, vs);
        Py_DECREF(s);
        if (w < 0 || (size_t)w >= cap - len) {
            PyErr_SetString(PyExc_ValueError, "the upload options are too long");
            return -1;
        }
        len += (size_t)w;
    }
    return 0;
}

static PyObject *client_upload(st_py_client *self, PyObject *args, PyObject *kw)
{
    static const char *const own[] = {"path", "name", "replace", "resume", "progress", "hint",
                                      "chunk", NULL};
    /* split kw into this call's own arguments and the import options */
    PyObject *mine = PyDict_New(), *opts = PyDict_New(), *path_b = NULL, *r = NULL;
    const char *name = NULL, *hint = NULL;
    int replace = 0, resume = 0;
    unsigned chunk = 0;
    PyObject *prog = Py_None, *path_o = NULL, *chunk_o = NULL;
    if (!mine || !opts)
        goto out;
    Py_ssize_t pos = 0;
    PyObject *k, *v;
    while (kw && PyDict_Next(kw, &pos, &k, &v)) {
        int is_own = 0;
        for (size_t i = 0; own[i]; i++)
            is_own |= PyUnicode_CompareWithASCIIString(k, own[i]) == 0;
        if (PyDict_SetItem(is_own ? mine : opts, k, v) < 0)
            goto out;
    }
    static char *kwlist[] = {"path", "name", "replace", "resume", "progress", "hint", "chunk",
                             NULL};
    if (!PyArg_ParseTupleAndKeywords(args, mine, "Os|$ppOzO:upload", kwlist, &path_o, &name,
                                     &replace, &resume, &prog, &hint, &chunk_o))
        goto out;
    if (st_py_uint_arg(chunk_o, "chunk", UINT32_MAX, &chunk) < 0)
        goto out;
    if (!PyUnicode_FSConverter(path_o, &path_b))
        goto out;
    char optstr[1024];
    if (options_string(opts, optstr, sizeof optstr) < 0)
        goto out;
    progress p;
    if (progress_arg(prog, &p) < 0)
        goto out;
    stc_upload_opts o;
    memset(&o, 0, sizeof o);
    o.hint = hint;
    o.options = optstr[0] ? optstr : NULL;
    o.flags = (replace ? STC_UPLOAD_REPLACE : 0) | (resume ? STC_UPLOAD_RESUME : 0);
    o.chunk = chunk;
    o.progress = progress_fn;
    o.user = &p;
    stc_upload_result res;
    int rc;
    if (st_py_client_enter(self) < 0)
        goto out;
    Py_BEGIN_ALLOW_THREADS
    rc = stc_upload_file(self->conn, PyBytes_AS_STRING(path_b), name, &o, &res);
    Py_END_ALLOW_THREADS
    if (progress_reraise(&p)) {
        st_py_client_leave(self);
        goto out;
    }
    if (rc) {
        st_py_client_fail(self, rc);
        st_py_client_leave(self);
        goto out;
    }
    st_py_client_leave(self);
    {
        const char *kind = stp_kind_name(res.kind), *dt = stp_dtype_name(res.dtype);
        r = Py_BuildValue("{s:s,s:s,s:I,s:s,s:I,s:K,s:I,s:K}", "name", res.name, "kind",
                          kind ? kind : "?", "nchan", res.nchan, "dtype", dt ? dt : "?",
                          "nfaces", (unsigned)res.nfaces, "memory",
                          (unsigned long long)res.memory, "crc32c", (unsigned)res.crc32c,
                          "resumed_from", (unsigned long long)res.resumed_from);
    }
out:
    Py_XDECREF(mine);
    Py_XDECREF(opts);
    Py_XDECREF(path_b);
    return r;
}

/* ---- compress jobs ---------------------------------------------------------------------------- */

static const char *const JOB_STATES[] = {"queued", "running", "done", "failed", "canceled"};

static PyObject *job_dict(const stc_job *j)
{
    const char *st = j->state < 5 ? JOB_STATES[j->state] : "?";
    return Py_BuildValue("{s:K,s:s,s:d,s:s,s:s}", "id", (unsigned long long)j->id, "state", st,
                         "progress", (double)j->progress, "result",
                         j->result ? stc_strerror(j->result) : "OK", "message", j->message);
}

static PyObject *client_compress_start(st_py_client *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"source", "target", "level", "seam_aware", "replace", NULL};
    const char *src, *dst;
    unsigned level = 5;
    int seam = 1, replace = 0, rc;
    uint64_t id = 0;
    PyObject *level_o = NULL;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "ss|O$pp:compress", kwlist, &src, &dst, &level_o,
                                     &seam, &replace) ||
        st_py_uint_arg(level_o, "level", 9, &level) < 0)
        return NULL;
    unsigned flags = (seam ? STC_COMPRESS_SEAM_AWARE : 0) | (replace ? STC_COMPRESS_REPLACE : 0);
    CALL_OR_FAIL(self, rc, stc_compress(c, src, dst, level, flags, &id));
    st_py_client_leave(self);
    return PyLong_FromUnsignedLongLong(id);
}

static PyObject *client_job_status(st_py_client *self, PyObject *args)
{
    unsigned long long id;
    stc_job j;
    int rc;
    if (!PyArg_ParseTuple(args, "K:_job_status", &id))
        return NULL;
    CALL_OR_FAIL(self, rc, stc_job_status(c, id, &j));
    st_py_client_leave(self);
    return job_dict(&j);
}

static PyObject *client_job_cancel(st_py_client *self, PyObject *args)
{
    unsigned long long id;
    stc_job j;
    int rc;
    if (!PyArg_ParseTuple(args, "K:_job_cancel", &id))
        return NULL;
    CALL_OR_FAIL(self, rc, stc_job_cancel(c, id, &j));
    st_py_client_leave(self);
    return job_dict(&j);
}

/* Waits in slices of at most 250 ms (a timeout= of its own; Ctrl-C is seen within a slice by
 * the interrupt hook, and between slices). */
static PyObject *client_job_wait(st_py_client *self, PyObject *args)
{
    unsigned long long id;
    PyObject *timeout_o = Py_None;
    if (!PyArg_ParseTuple(args, "K|O:_job_wait", &id, &timeout_o))
        return NULL;
    double left = -1;
    if (timeout_o != Py_None) {
        left = PyFloat_AsDouble(timeout_o);
        if (left == -1.0 && PyErr_Occurred())
            return NULL;
        if (isnan(left)) {      /* NaN used to poll in a busy loop until the job ended */
            PyErr_SetString(PyExc_ValueError, "timeout must be a number of seconds or None");
            return NULL;
        }
        if (left < 0)
            left = 0;           /* passed already: one poll, then TimedOut */
    }
    stc_job j;
    memset(&j, 0, sizeof j);
    for (;;) {
        int slice = left < 0 || left > 0.25 ? 250 : ms_of(left), rc;
        if (st_py_client_enter(self) < 0)
            return NULL;
        Py_BEGIN_ALLOW_THREADS
        rc = stc_job_wait(self->conn, id, slice, &j);
        Py_END_ALLOW_THREADS
        if (rc == 0) {
            st_py_client_leave(self);
            return job_dict(&j);
        }
        if (rc != STC_ETIMEDOUT || stc_error(self->conn)) {
            st_py_client_fail(self, rc);
            st_py_client_leave(self);
            return NULL;
        }
        st_py_client_leave(self);
        if (PyErr_CheckSignals() < 0)
            return NULL;
        if (left >= 0) {
            left -= slice / 1000.0;
            if (left <= 0)
                return st_py_raise(STC_ETIMEDOUT, "the job is still running");
        }
    }
}

/* ---- fetch ------------------------------------------------------------------------------------- */

/* The fetch formats by name: the protocol's list (protocol/proto_lists.h STP_FETCH_FORMATS,
 * parsed by stp_fetch_format_parse, case-insensitive), so a format the protocol gains is
 * known here without an edit. A number is passed to libseamtex as it is (which refuses one
 * its protocol list lacks with InvalidArgument). */
#define FETCH_NAME_(NAME, str, value) " " str
static const char FETCH_NAMES[] = STP_FETCH_FORMATS(FETCH_NAME_);
#undef FETCH_NAME_

static int fetch_format(PyObject *fmt, const char *path, unsigned *out)
{
    const char *name;
    if (fmt && fmt != Py_None && (PyBool_Check(fmt) || !(PyLong_Check(fmt) ||
                                                        PyUnicode_Check(fmt)))) {
        /* a float or bytes used to raise "bad argument type for built-in operation" */
        PyErr_Format(PyExc_TypeError, "format must be a name (one of:%s), a wire number or "
                     "None, not %.80s", FETCH_NAMES, Py_TYPE(fmt)->tp_name);
        return -1;
    }
    if (fmt && fmt != Py_None && PyLong_Check(fmt)) {
        unsigned long v = PyLong_AsUnsignedLong(fmt);
        if (PyErr_Occurred() || v > 255) {
            PyErr_Clear();
            PyErr_SetString(PyExc_ValueError, "a fetch format number is 0..255");
            return -1;
        }
        *out = (unsigned)v;
        return 0;
    }
    if (fmt && fmt != Py_None) {
        if (!(name = PyUnicode_AsUTF8(fmt)))
            return -1;
    } else {
        const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
        if (!dot || (slash && dot < slash)) {
            PyErr_Format(PyExc_ValueError, "%s has no extension: pass format= one of:%s", path,
                         FETCH_NAMES);
            return -1;
        }
        name = dot + 1;
    }
    int f = stp_fetch_format_parse(name);
    if (f >= 0) {
        *out = (unsigned)f;
        return 0;
    }
    PyErr_Format(PyExc_ValueError, "unknown fetch format '%s' (one of:%s; a number is passed "
                 "through to the server)", name, FETCH_NAMES);
    return -1;
}

static PyObject *client_fetch(st_py_client *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"name", "path", "format", "progress", NULL};
    const char *name;
    PyObject *path_o, *path_b = NULL, *fmt = Py_None, *prog = Py_None;
    unsigned format;
    progress p;
    int rc;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "sO|O$O:fetch", kwlist, &name, &path_o, &fmt,
                                     &prog))
        return NULL;
    if (!PyUnicode_FSConverter(path_o, &path_b))
        return NULL;
    if (fetch_format(fmt, PyBytes_AS_STRING(path_b), &format) < 0 ||
        progress_arg(prog, &p) < 0 || st_py_client_enter(self) < 0) {
        Py_DECREF(path_b);
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    rc = stc_fetch_file(self->conn, name, format, PyBytes_AS_STRING(path_b), progress_fn, &p);
    Py_END_ALLOW_THREADS
    if (progress_reraise(&p) || (rc && !st_py_client_fail(self, rc))) {
        st_py_client_leave(self);
        Py_DECREF(path_b);
        return NULL;
    }
    st_py_client_leave(self);
    Py_DECREF(path_b);
    Py_RETURN_NONE;
}

/* ---- attributes ---------------------------------------------------------------------------------- */

static PyObject *client_get_closed(st_py_client *self, void *closure)
{
    (void)closure;
    return PyBool_FromLong(self->conn == NULL);
}

static PyObject *client_get_server(st_py_client *self, void *closure)
{
    (void)closure;
    /* no lock: HELLO's facts never change (it used to wait behind another thread's call) */
    if (st_py_client_usable(self) < 0)
        return NULL;
    const stc_server s = self->hello;
    return Py_BuildValue("{s:I,s:I,s:I,s:I,s:I,s:I,s:O,s:s}", "version", s.version, "caps",
                         (unsigned)s.caps, "max_body", (unsigned)s.max_body, "max_batch",
                         (unsigned)s.max_batch, "max_chunk", (unsigned)s.max_chunk,
                         "max_inflight", (unsigned)s.max_inflight, "authenticated",
                         s.authenticated ? Py_True : Py_False, "name", s.name);
}

static PyObject *client_get_timeout(st_py_client *self, void *closure)
{
    (void)closure;
    if (self->timeout > 0)
        return PyFloat_FromDouble(self->timeout);
    Py_RETURN_NONE;
}

static int client_set_timeout(st_py_client *self, PyObject *v, void *closure)
{
    (void)closure;
    double t = 0;
    if (!v) {                   /* del c.timeout used to mean "no timeout" without a word */
        PyErr_SetString(PyExc_AttributeError, "timeout cannot be deleted (set it to None for "
                        "no timeout)");
        return -1;
    }
    if (v != Py_None) {
        t = PyFloat_AsDouble(v);
        if (t == -1.0 && PyErr_Occurred())
            return -1;
        if (!(t > 0)) {
            PyErr_SetString(PyExc_ValueError, "timeout must be > 0 seconds, or None for none");
            return -1;
        }
    }
    if (st_py_client_enter(self) < 0)
        return -1;
    stc_set_timeout(self->conn, ms_of(t));
    self->timeout = t;
    st_py_client_leave(self);
    return 0;
}

static PyObject *client_get_times(st_py_client *self, void *closure)
{
    (void)closure;
    return Py_BuildValue("{s:d,s:d,s:d}", "pack", self->times[0], "call", self->times[1],
                         "copy", self->times[2]);
}

static PyGetSetDef client_getset[] = {
    {"last_sample_times", (getter)client_get_times, NULL,
     "Where the last sample / sample_dir call spent its time, in seconds: 'pack' (reading\n"
     "the arrays into query records), 'call' (libseamtex's stc_sample: encoding, the\n"
     "network, the server, decoding), 'copy' (copying the result into the returned arrays).",
     NULL},
    {"closed", (getter)client_get_closed, NULL, "True once close() was called.", NULL},
    {"server", (getter)client_get_server, NULL,
     "What the server told in HELLO: version, caps, max_body, max_batch, max_chunk,\n"
     "max_inflight, authenticated, name.", NULL},
    {"timeout", (getter)client_get_timeout, (setter)client_set_timeout,
     "Per-request timeout in seconds (None = none).", NULL},
    {"shm_status", (getter)st_py_shm_status, NULL,
     "Shared-memory sampling (Client(shm=...)): attached (bool), bytes (the region, 0 when\n"
     "none), via_shm and via_socket (SAMPLE requests sent each way so far), reason (why no\n"
     "region: None when attached).", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyMethodDef client_methods[] = {
    {"close", (PyCFunction)client_close, METH_NOARGS,
     "close() -> None\n\nCloses the connection (again: no-op). Later calls raise ClosedError."},
    {"__enter__", (PyCFunction)client_enter_ctx, METH_NOARGS, "Returns the client."},
    {"__exit__", (PyCFunction)client_exit_ctx, METH_VARARGS, "Closes the client."},
    {"ping", (PyCFunction)client_ping, METH_NOARGS,
     "ping() -> float\n\nOne PING round trip; returns its duration in seconds."},
    {"ls", (PyCFunction)client_ls, METH_NOARGS,
     "ls() -> list[dict]\n\nEvery set on the server: dicts with name, kind ('perface', 'cube',\n"
     "'atlas', 'bc1'), nchan, dtype ('u8', 'u16', 'half', 'f32'), nfaces, memory (bytes)."},
    {"info", (PyCFunction)(void (*)(void))client_info, METH_VARARGS | METH_KEYWORDS,
     "info(name, faces=None) -> dict\n\nFacts about one set (nfaces, nchan, dtype, kind,\n"
     "sizes, mesh facts, ...). faces=count or (first, count) also returns per-face records\n"
     "(id, w, h, adjface, adjedge, flags, nlevels) in 'faces'. Raises NotFound."},
    {"sample", (PyCFunction)(void (*)(void))st_py_sample, METH_VARARGS | METH_KEYWORDS,
     st_py_sample_doc},
    {"sample_dir", (PyCFunction)(void (*)(void))st_py_sample_dir, METH_VARARGS | METH_KEYWORDS,
     st_py_sample_dir_doc},
    {"upload", (PyCFunction)(void (*)(void))client_upload, METH_VARARGS | METH_KEYWORDS,
     "upload(path, name, *, replace=False, resume=False, progress=None, hint=None, chunk=0,\n"
     "       **options) -> dict\n\n"
     "Uploads the file at path as set name. options become the server's import option\n"
     "string 'k=v k=v': cube='latlong:512', texture='duck-tex', colorspace='srgb'.\n"
     "progress(done, total) is called after each acknowledged chunk; an exception raised in\n"
     "it (or Ctrl-C) aborts the upload and propagates. hint names the format ('ptx', 'png',\n"
     "...; default: from the extension). Returns name, kind, nchan, dtype, nfaces, memory,\n"
     "crc32c, resumed_from. Raises Exists unless replace=True."},
    {"delete", (PyCFunction)client_delete, METH_VARARGS,
     "delete(name) -> None\n\nDeletes a set. Raises NotFound."},
    {"stats", (PyCFunction)client_stats, METH_NOARGS,
     "stats() -> dict\n\nThe server's counters: key -> int or float."},
    {"_compress", (PyCFunction)(void (*)(void))client_compress_start,
     METH_VARARGS | METH_KEYWORDS,
     "_compress(source, target, level=5, *, seam_aware=True, replace=False) -> int\n\n"
     "Starts a BC1 compress job; returns its id (Client.compress wraps it in a Job)."},
    {"_job_status", (PyCFunction)client_job_status, METH_VARARGS,
     "_job_status(id) -> dict\n\nid, state, progress, result, message of a job."},
    {"_job_cancel", (PyCFunction)client_job_cancel, METH_VARARGS,
     "_job_cancel(id) -> dict\n\nAsks the server to cancel a job; returns its state."},
    {"_job_wait", (PyCFunction)client_job_wait, METH_VARARGS,
     "_job_wait(id, timeout=None) -> dict\n\nWaits until the job is done (its dict), failed\n"
     "or was cancelled (the job's error is raised), or timeout seconds passed (TimedOut)."},
    {"fetch", (PyCFunction)(void (*)(void))client_fetch, METH_VARARGS | METH_KEYWORDS,
     "fetch(name, path, format=None, *, progress=None) -> None\n\n"
     "Downloads a set to path (written to path + '.part', checked against the server's\n"
     "CRC32C, renamed onto path). format: 'ptx', 'dds', 'exr', 'png', 'obj' (the protocol's\n"
     "list; which fits which set kind: PROTOCOL.md 4.10) or the wire number; default: from\n"
     "path's extension."},
    {NULL, NULL, 0, NULL},
};

PyTypeObject st_py_client_type = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "seamtex._seamtex.Client",
    .tp_basicsize = sizeof(st_py_client),
    .tp_dealloc = (destructor)client_dealloc,
    .tp_repr = (reprfunc)client_repr,
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_BASETYPE,
    .tp_doc = "Client(host='127.0.0.1', port=7450, token=None, timeout=10.0, *, numpy=None,\n"
              "       client_name='seamtex-python', shm='auto', shm_bytes=64 << 20)\n\n"
              "One connection to seamtexd (HELLO done). timeout: seconds for the connect and\n"
              "for each request (None = none). numpy: None = sample results are numpy arrays\n"
              "when numpy imports, else seamtex.Array; True / False force either. shm: on a\n"
              "'unix:/path' host, sample through a shared-memory region of shm_bytes ('auto':\n"
              "or fall back to the socket, reason in shm_status; True: or raise why not -\n"
              "Unsupported, TooLarge, InvalidArgument on TCP; False: never). A Client is a\n"
              "context manager (closed on exit); it may be shared by threads (calls take\n"
              "turns), though one Client per thread runs them in parallel.",
    .tp_methods = client_methods,
    .tp_getset = client_getset,
    .tp_init = (initproc)client_init,
    .tp_new = PyType_GenericNew,
};
