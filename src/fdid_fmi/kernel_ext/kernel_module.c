/* kernel_module.c -- makes fdid_core.c (the FMU's simulation core) an importable extension
 * module, fdid_fmi._kernel, so that it is built and installed with the package. Its functions
 * are called through ctypes (fdid_fmi/kernel.py); the module itself has no Python methods. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

static struct PyModuleDef kernel_module = {
    PyModuleDef_HEAD_INIT, "_kernel",
    "The fdid-fmi simulation core (fmu_templates/fdid_core.c), used through ctypes.", -1, NULL,
    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__kernel(void) { return PyModule_Create(&kernel_module); }
