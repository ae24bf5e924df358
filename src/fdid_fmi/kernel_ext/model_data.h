/* model_data.h for the in-process kernel (fdid_fmi._kernel): the model arrives at run time as
 * an FdidModel built by fdid_fmi/kernel.py, so there is no generated data here; every feature
 * function is compiled in (the FMU build enables libm only for models that need it). */
#ifndef FDID_MODEL_DATA_H
#define FDID_MODEL_DATA_H
#define FDID_USE_LIBM 1
#include "fdid_model.h"
#endif
