/* python/seamtex/_seamtex.c - the module seamtex._seamtex: the CPython extension over
 * libseamtex that the package seamtex (__init__.py) re-exports.
 *
 * Owns: module creation, the types (Client, Array), the exception classes (pyerrors.c) and
 * the name lists a caller may use: MODES, FILTERS, FORMATS, ZERO_RULES and QSTATUS, all
 * generated from protocol/proto_lists.h, so that a name added to the protocol shows up here
 * without an edit.
 * Does not own: the calls (pyclient.c, pysample.c).
 */
#include "pyseamtex.h"

#include "proto.h"

/* A tuple of the names of one protocol list. */
static PyObject *names3(const char *const *names, size_t n)
{
    PyObject *t = PyTuple_New((Py_ssize_t)n);
    for (size_t i = 0; t && i < n; i++) {
        PyObject *s = PyUnicode_FromString(names[i]);
        if (!s) {
            Py_CLEAR(t);
            break;
        }
        PyTuple_SET_ITEM(t, (Py_ssize_t)i, s);
    }
    return t;
}

#define STR3_(NAME, str, value) str,
#define STR4_(NAME, str, value, size) str,
#define QSTR_(NAME, value) #NAME,
static const char *const MODES[] = {STP_MODES(STR3_)};
static const char *const FILTERS[] = {STP_FILTERS(STR3_)};
static const char *const ZERO_RULES[] = {STP_ZERO_RULES(STR3_)};
static const char *const FORMATS[] = {STP_OUTFMTS(STR4_)};
static const char *const QSTATUS[] = {STP_QSTATUSES(QSTR_)};
#undef STR3_
#undef STR4_
#undef QSTR_
#define COUNT_(a) (sizeof(a) / sizeof((a)[0]))

static int add_lists(PyObject *m)
{
    struct { const char *name; const char *const *v; size_t n; } lists[] = {
        {"MODES", MODES, COUNT_(MODES)},
        {"FILTERS", FILTERS, COUNT_(FILTERS)},
        {"ZERO_RULES", ZERO_RULES, COUNT_(ZERO_RULES)},
        {"FORMATS", FORMATS, COUNT_(FORMATS)},
        {"QSTATUS", QSTATUS, COUNT_(QSTATUS)},
    };
    for (size_t i = 0; i < COUNT_(lists); i++) {
        PyObject *t = names3(lists[i].v, lists[i].n);
        if (!t || PyModule_AddObject(m, lists[i].name, t) < 0) {
            Py_XDECREF(t);
            return -1;
        }
    }
    /* per-query statuses as constants: Q_OK = 0, Q_BAD_FACE = 1, ... */
#define QCONST_(NAME, value)                                                           \
    if (PyModule_AddIntConstant(m, "Q_" #NAME, value) < 0)                             \
        return -1;
    STP_QSTATUSES(QCONST_)
#undef QCONST_
    return 0;
}

static struct PyModuleDef seamtex_module = {
    PyModuleDef_HEAD_INIT,
    .m_name = "seamtex._seamtex",
    .m_doc = "The C extension behind the seamtex package (libseamtex bound to Python).",
    .m_size = -1,
};

PyMODINIT_FUNC PyInit__seamtex(void)
{
    if (PyType_Ready(&st_py_client_type) < 0 || PyType_Ready(&st_py_array_type) < 0)
        return NULL;
    static int watching;          /* once per process, however often the module is created */
    if (!watching) {
        if (st_py_fork_watch() < 0) {
            PyErr_SetString(PyExc_OSError, "pthread_atfork failed");
            return NULL;
        }
        watching = 1;
    }
    /* the thread whose signal handlers run (st_py_interrupt asks on that one only) */
    PyObject *th = PyImport_ImportModule("threading");
    PyObject *mt = th ? PyObject_CallMethod(th, "main_thread", NULL) : NULL;
    PyObject *id = mt ? PyObject_GetAttrString(mt, "ident") : NULL;
    Py_XDECREF(th);
    Py_XDECREF(mt);
    if (!id)
        return NULL;
    st_py_main_thread = PyLong_AsUnsignedLong(id);
    Py_DECREF(id);
    if (PyErr_Occurred())
        return NULL;
    PyObject *m = PyModule_Create(&seamtex_module);
    if (!m)
        return NULL;
    Py_INCREF(&st_py_client_type);
    if (PyModule_AddObject(m, "Client", (PyObject *)&st_py_client_type) < 0) {
        Py_DECREF(&st_py_client_type);
        goto fail;
    }
    Py_INCREF(&st_py_array_type);
    if (PyModule_AddObject(m, "Array", (PyObject *)&st_py_array_type) < 0) {
        Py_DECREF(&st_py_array_type);
        goto fail;
    }
    if (st_py_errors_init(m) < 0 || add_lists(m) < 0)
        goto fail;
    return m;
fail:
    Py_DECREF(m);
    return NULL;
}
