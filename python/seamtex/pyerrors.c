/* python/seamtex/pyerrors.c - seamtex.Error and its subclasses.
 *
 * Owns: one exception class per server status, generated from the protocol's status list
 * (protocol/proto_lists.h STP_STATUSES: NOT_FOUND -> NotFound, TOO_LARGE -> TooLarge, ...), one
 * per group of libseamtex's local codes (also derived from Python's matching built-in:
 * TimedOut is a TimeoutError, ConnectFailed a ConnectionError, ...), and raising them with
 * .status (the code's stable name, stc_strerror), .code (the stc_err number) and .message.
 * Does not own: the messages (the server's or libseamtex's, passed through).
 */
#include "pyseamtex.h"

#include <ctype.h>
#include <string.h>

#include "proto.h"

/* The classes by stc_err code: server statuses at STC_SERVER_BASE + status, local codes at
 * -code. Filled once by st_py_errors_init (module state of a single-phase module). */
#define N_SLOTS (STC_SERVER_BASE + STP_S_COUNT_)
static PyObject *g_class[N_SLOTS];
static PyObject *g_error;     /* seamtex.Error */
static PyObject *g_closed;    /* seamtex.ClosedError */

static const struct {
    int         code;
    const char *name;
    const char *doc;
} LOCAL[] = {
    {STC_EINVAL,    "InvalidArgument",  "libseamtex refused an argument (EINVAL)."},
    {STC_ENOMEM,    "OutOfMemory",      "The client ran out of memory (ENOMEM)."},
    {STC_ECONNECT,  "ConnectFailed",    "Name resolution or connect() failed (ECONNECT)."},
    {STC_EIO,       "ConnectionLost",   "The connection broke (EIO, ECLOSED); open a new Client."},
    {STC_ECLOSED,   "ConnectionLost",   NULL},
    {STC_EPROTO,    "ProtocolError",    "The server broke the protocol (EPROTO)."},
    {STC_ETIMEDOUT, "TimedOut",         "A connect or request timeout (ETIMEDOUT); the client stays usable."},
    {STC_EFILE,     "FileError",        "A local file could not be read or written (EFILE)."},
    {STC_ECHECKSUM, "ChecksumMismatch", "Downloaded data did not match its checksum (ECHECKSUM)."},
    {STC_ESTATE,    "StateError",       "A call that is not allowed now (ESTATE)."},
    {STC_ECANCELED, "Aborted",          "A progress callback stopped a transfer (ECANCELED)."},
    /* the interrupt hook said stop: the module raises the signal handler's exception
     * instead (KeyboardInterrupt); the class only names the code */
    {STC_EINTERRUPTED, "Aborted",       NULL},
};

static PyObject *builtin_base(int code)
{
    switch (code) {
    case STC_EINVAL: return PyExc_ValueError;
    case STC_ENOMEM: return PyExc_MemoryError;
    case STC_ECONNECT: case STC_EIO: case STC_ECLOSED: case STC_EPROTO:
        return PyExc_ConnectionError;
    case STC_ETIMEDOUT: return PyExc_TimeoutError;
    case STC_EFILE: return PyExc_OSError;
    default: return NULL;
    }
}

/* NOT_FOUND -> NotFound; words of one or two letters stay upper case (IO). */
static void camel(const char *s, char *out, size_t cap)
{
    size_t o = 0;
    while (*s && o + 3 < cap) {
        size_t wl = strcspn(s, "_");
        for (size_t i = 0; i < wl && o + 1 < cap; i++)
            out[o++] = (char)(i == 0 || wl <= 2 ? toupper((unsigned char)s[i])
                                                : tolower((unsigned char)s[i]));
        s += wl;
        if (*s == '_')
            s++;
    }
    out[o] = 0;
}

static int add_class(PyObject *m, const char *name, const char *doc, PyObject *bases,
                     PyObject **out)
{
    char qual[96];
    snprintf(qual, sizeof qual, "seamtex.%s", name);
    PyObject *cls = PyObject_GetAttrString(m, name);
    if (cls) {                    /* two codes share a class (ConnectionLost) */
        *out = cls;
        return 0;
    }
    PyErr_Clear();
    cls = PyErr_NewExceptionWithDoc(qual, doc, bases, NULL);
    if (!cls)
        return -1;
    if (PyModule_AddObject(m, name, cls) < 0) {
        Py_DECREF(cls);
        return -1;
    }
    Py_INCREF(cls);
    *out = cls;
    return 0;
}

int st_py_errors_init(PyObject *m)
{
    /* class attributes: what an Error raised by Python code (not by the library) has */
    PyObject *d = Py_BuildValue("{s:O,s:i,s:s}", "status", Py_None, "code", 0, "message", ""),
             *by_status = PyDict_New();
    if (!d || !by_status)
        goto fail;
    g_error = PyErr_NewExceptionWithDoc(
        "seamtex.Error",
        "Base class of every seamtex error.\n\n"
        "Attributes: status (the stable name of the code: 'NOT_FOUND', 'ETIMEDOUT', ...),\n"
        "code (libseamtex's negative stc_err number), message (the server's or the\n"
        "library's message).",
        NULL, d);
    Py_CLEAR(d);
    if (!g_error)
        goto fail;
    Py_INCREF(g_error);
    if (PyModule_AddObject(m, "Error", g_error) < 0)
        goto fail;

    /* server statuses, from the protocol's list */
    for (unsigned s = 1; s < STP_S_COUNT_; s++) {
        char name[64], doc[160];
        const char *sn = stp_status_name(s);
        camel(sn, name, sizeof name);
        snprintf(doc, sizeof doc, "The server answered %s (protocol status %u; PROTOCOL.md 3).",
                 sn, s);
        if (add_class(m, name, doc, g_error, &g_class[STC_SERVER_BASE + s]) < 0)
            goto fail;
        if (PyDict_SetItemString(by_status, sn, g_class[STC_SERVER_BASE + s]) < 0)
            goto fail;
    }
    /* local codes */
    for (size_t i = 0; i < sizeof LOCAL / sizeof LOCAL[0]; i++) {
        PyObject *b = builtin_base(LOCAL[i].code), *bases;
        bases = b ? PyTuple_Pack(2, g_error, b) : PyTuple_Pack(1, g_error);
        if (!bases)
            goto fail;
        int rc = add_class(m, LOCAL[i].name, LOCAL[i].doc, bases, &g_class[-LOCAL[i].code]);
        Py_DECREF(bases);
        if (rc < 0 ||
            PyDict_SetItemString(by_status, stc_strerror(LOCAL[i].code), g_class[-LOCAL[i].code]) < 0)
            goto fail;
    }
    {
        PyObject *bases = PyTuple_Pack(2, g_error, PyExc_ValueError);
        if (!bases)
            goto fail;
        int rc = add_class(m, "ClosedError", "An operation on a closed Client.", bases, &g_closed);
        Py_DECREF(bases);
        if (rc < 0)
            goto fail;
    }
    if (PyModule_AddObject(m, "errors", by_status) < 0)
        goto fail;
    return 0;
fail:
    Py_XDECREF(d);
    Py_XDECREF(by_status);
    return -1;
}

/* Raises cls(msg) with .status (the name of code, None for code 0), .code and .message. */
static PyObject *raise_as(PyObject *cls, int code, const char *msg)
{
    PyObject *e = PyObject_CallFunction(cls, "s", msg);
    if (!e)
        return NULL;
    PyObject *st = code ? PyUnicode_FromString(stc_strerror(code)) : Py_None,
             *cd = PyLong_FromLong(code), *ms = PyUnicode_FromString(msg);
    if (!code)
        Py_INCREF(st);
    if (st && cd && ms) {
        PyObject_SetAttrString(e, "status", st);
        PyObject_SetAttrString(e, "code", cd);
        PyObject_SetAttrString(e, "message", ms);
    }
    Py_XDECREF(st);
    Py_XDECREF(cd);
    Py_XDECREF(ms);
    if (!PyErr_Occurred())
        PyErr_SetObject((PyObject *)Py_TYPE(e), e);
    Py_DECREF(e);
    return NULL;
}

PyObject *st_py_raise(int code, const char *msg)
{
    if (!msg || !*msg)
        msg = stc_strerror(code);
    return raise_as(st_py_raise_class(code), code, msg);
}

PyObject *st_py_raise_closed(const char *msg)
{
    /* its message in .message too (it used to be the class's "", only str(e) had it) */
    return raise_as(g_closed, 0, msg);
}

PyObject *st_py_raise_class(int code)
{
    PyObject *cls = code < 0 && -code < N_SLOTS ? g_class[-code] : NULL;
    return cls ? cls : g_error;
}

PyObject *st_py_closed_error(void)
{
    return g_closed;
}
