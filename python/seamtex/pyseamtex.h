/* python/seamtex/pyseamtex.h - internals shared by the files of the CPython extension
 * seamtex._seamtex (not installed, not a public API).
 *
 * Owns: the Client object's layout and its locking rule, the Array type (a small
 * buffer-exporting array so that the module needs no numpy), the exception classes derived
 * from the protocol's status list, the column readers that turn buffer-protocol arguments
 * into query fields.
 * Does not own: the protocol or the network (libseamtex, client/seamtex.h): every call goes
 * through stc_*.
 *
 * Files: _seamtex.c (module init, constants), pyclient.c (Client: connect, ls, info, upload,
 * jobs, fetch, stats, ...), pysample.c (sample, sample_dir), pyshm.c (shared memory: shm=,
 * shm_status), pyarray.c (Array), pyerrors.c (exceptions).
 *
 * GIL: every stc_* call that may wait on the network runs between Py_BEGIN_ALLOW_THREADS and
 * Py_END_ALLOW_THREADS; while it waits, libseamtex's interrupt hook (st_py_interrupt) takes
 * the GIL briefly on the main thread to run signal handlers (Ctrl-C). A Client holds one connection, used by one thread at a time (the
 * library's rule): st_py_client_enter takes the Client's lock (waiting for it with the GIL
 * released), st_py_client_leave gives it back.
 */
#ifndef ST_PYSEAMTEX_H
#define ST_PYSEAMTEX_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <pythread.h>

#include "seamtex.h"

/* ---- Client (pyclient.c) --------------------------------------------------------------------- */

typedef struct st_py_client {
    PyObject_HEAD
    stc_conn          *conn;      /* NULL once closed */
    PyThread_type_lock lock;      /* held by the thread using conn */
    unsigned long      owner;     /* that thread's ident while it holds the lock, else 0 */
    long               pid;       /* the process that connected (for the message) */
    unsigned long      fork_gen;  /* st_py_fork_gen then: after fork a child's calls raise
                                     StateError (libseamtex refuses them too) before the
                                     lock, which a parent's thread may have held */
    double             timeout;   /* seconds per request; <= 0 = none */
    int                numpy;     /* -1 auto, 0 never, 1 always: arrays returned by sample */
    char               host[256];
    unsigned           port;
    void              *scratch;   /* query records of the last sample call (grow-only, reused:
                                     no fresh pages to fault in for each big batch); under lock */
    size_t             scratch_cap;
    double             times[3];  /* the last sample call: packing, stc_sample, copying out (s) */
    size_t             shm_bytes; /* the shared-memory region attached (pyshm.c), 0: none */
    char               shm_why[256];  /* why there is none */
    /* Read by Client.server and shm_status without the lock (they used to wait behind another
     * thread's long call): written, like conn, only with the GIL held, which orders them. */
    stc_server         hello;     /* what HELLO told, copied at connect (it never changes) */
    uint64_t           via_shm, via_sock;  /* stc_shm_counts as of the last call's end */
    /* What a signal handler raised while this Client's call waited (KeyboardInterrupt for
     * Ctrl-C): the libseamtex interrupt hook (st_py_interrupt) keeps it here and the call
     * returns STC_EINTERRUPTED, which st_py_client_fail turns back into it. Written by the
     * thread holding the lock (the GIL held); cleared by st_py_client_leave. */
    PyObject          *intr_type, *intr_value, *intr_tb;
} st_py_client;

/* libseamtex's interrupt hook (stc_opts.interrupt, user = the Client), called while a call
 * waits with the GIL released: on the main thread (the only one where Python runs signal
 * handlers) it takes the GIL, runs PyErr_CheckSignals and says stop when a handler raised;
 * on any other thread it returns 0 without the GIL. Installed with ST_PY_INTERRUPT_MS. */
int st_py_interrupt(void *user);
/* How often a wait asks the hook besides when a signal interrupts it (EINTR): covers a
 * SIGINT the kernel gave to another thread of the process. */
#define ST_PY_INTERRUPT_MS 100
/* The main thread's ident (threading.main_thread().ident at import). */
extern unsigned long st_py_main_thread;

/* Forks this process has gone through as a child (pthread_atfork, registered by
 * st_py_fork_watch at import): a Client connected at another count is its parent's. A load,
 * where getpid is a system call per call (1.3-2 us on this VM). */
extern volatile unsigned long st_py_fork_gen;
int st_py_fork_watch(void);

/* CLOCK_MONOTONIC in seconds. */
double st_py_now(void);

/* An integer argument `what` of 0..max into *out (None keeps *out); TypeError for a
 * non-integer, ValueError naming the argument for one out of range (PyArg's "I" would wrap
 * it silently: chunk=2**32 + 1 became 1). Returns -1 with the exception set. */
int st_py_uint_arg(PyObject *o, const char *what, unsigned long max, unsigned *out);

/* The client's scratch block of at least bytes (lock held; GIL not needed); NULL when out of
 * memory. */
void *st_py_client_scratch(st_py_client *self, size_t bytes);

extern PyTypeObject st_py_client_type;

/* Takes the client's lock (GIL released while waiting); raises (and returns -1) when the
 * client is closed, when the calling thread holds it already (a progress callback calling
 * its own Client would otherwise wait for itself forever) or when this is not the process
 * that connected (a child after fork: StateError). */
int st_py_client_enter(st_py_client *self);
/* Gives the lock back (GIL held), keeping the shared-memory counts for shm_status (and
 * dropping a signal's exception that another exception raised by the call has overtaken). */
void st_py_client_leave(st_py_client *self);
/* For the attributes read without the lock (server, shm_status; GIL held): raises as
 * st_py_client_enter does for a closed Client or a child after fork, without waiting. */
int st_py_client_usable(st_py_client *self);
/* Raises the exception for rc (an stc_err code) with the connection's message; call with the
 * lock held (the message belongs to the connection). When the interrupt hook stopped the call
 * (STC_EINTERRUPTED) it raises what the signal handler raised instead. Returns NULL. */
PyObject *st_py_client_fail(st_py_client *self, int rc);

/* ---- shared memory (pyshm.c) ------------------------------------------------------------------ */

/* Default of Client(shm_bytes=...): room for a 10^6-query f32 call (28 MB of queries, its
 * reply overwriting them) and then some. */
#define ST_PY_SHM_DEFAULT ((Py_ssize_t)64 << 20)
/* After connecting (GIL held, the Client not yet shared): the shm policy of Client(shm=...)
 * (False / None, True, "auto"; NULL = not given = "auto") with a region of `bytes`. 0 (attached, or not with the reason
 * kept under auto / False), or -1 with an exception set (a bad argument; shm=True and no
 * region; the connection broke). */
int st_py_shm_open(st_py_client *self, PyObject *shm_o, Py_ssize_t bytes);
/* Getter of Client.shm_status: {attached, bytes, via_shm, via_socket, reason}. */
PyObject *st_py_shm_status(st_py_client *self, void *closure);

/* ---- sampling (pysample.c) -------------------------------------------------------------------- */

PyObject *st_py_sample(st_py_client *self, PyObject *args, PyObject *kw);
PyObject *st_py_sample_dir(st_py_client *self, PyObject *args, PyObject *kw);
extern const char st_py_sample_doc[];
extern const char st_py_sample_dir_doc[];

/* ---- Array (pyarray.c) ------------------------------------------------------------------------- */

extern PyTypeObject st_py_array_type;
/* A new Array that takes ownership of data (malloc'd; freed with free()): ndim 1 or 2,
 * format "f" / "B" / "H" / "I", C-contiguous. On failure frees data and returns NULL. */
PyObject *st_py_array_wrap(void *data, const char *format, Py_ssize_t itemsize, int ndim,
                           Py_ssize_t n0, Py_ssize_t n1);
/* obj as a numpy array when the client asks for numpy (or "auto" and numpy imports), else
 * obj itself. Steals obj's reference. */
PyObject *st_py_array_out(st_py_client *self, PyObject *obj);

/* ---- exceptions (pyerrors.c) ------------------------------------------------------------------ */

/* Creates seamtex.Error and its subclasses in module m. 0 or -1. */
int st_py_errors_init(PyObject *m);
/* Raises the exception class of code with message msg (stc_strerror(code) when empty);
 * returns NULL. */
PyObject *st_py_raise(int code, const char *msg);
/* The exception class of an stc_err code (seamtex.Error when it has none of its own). */
PyObject *st_py_raise_class(int code);
/* The class for "the client is closed". */
PyObject *st_py_closed_error(void);
/* Raises ClosedError with message msg (also its .message; .status None, .code 0: no
 * libseamtex code). Returns NULL. */
PyObject *st_py_raise_closed(const char *msg);

#endif
