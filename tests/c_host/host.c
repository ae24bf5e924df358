/* host.c -- a minimal FMI 2.0 co-simulation master in C, used by the tests and benchmarks.
 *
 * It loads an FMU binary with dlopen (LoadLibrary on Windows), with no Python involved, and
 *   run     drives N independent instances interleaved step by step; instance i gets the
 *           inputs scaled by (1 + 0.25 i); writes every instance's outputs (float64) to a file;
 *   bench   one instance, times the stepping loop, prints "steps_per_second <value>";
 *   errors  exercises misuse (wrong step size, NaN input, unknown value reference, calls in
 *           the wrong order, cancelStep, FMU state get/set/serialize) and checks every status;
 *           prints "errors ok" and exits 0 when every call returned what it should.
 *
 * usage: host MODE LIB GUID Ts NSTEPS COMM NINST IN_FILE OUT_FILE NIN NOUT vr_in... vr_out...
 *             [NPAR vr value ...]
 * IN_FILE holds NSTEPS*NIN float64 (row = sample); OUT_FILE gets NINST*(NSTEPS/COMM)*NOUT.
 * The input of sample k is set before the outputs of sample k are read, then doStep(t_k, COMM*Ts).
 */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef _WIN32
#include <windows.h>
#else
#include <dlfcn.h>
#endif

#include "fmi2Functions.h"

static int n_error_messages = 0;
static int quiet = 0;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    va_list ap;
    (void)env;
    if (status == fmi2Error || status == fmi2Fatal) n_error_messages++;
    if (quiet) return;
    fprintf(stderr, "[%s|%s|%d] ", name, category, (int)status);
    va_start(ap, message);
    vfprintf(stderr, message, ap);
    va_end(ap);
    fputc('\n', stderr);
}

typedef struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *freeInstance;
    fmi2SetupExperimentTYPE *setupExperiment;
    fmi2EnterInitializationModeTYPE *enterInit;
    fmi2ExitInitializationModeTYPE *exitInit;
    fmi2TerminateTYPE *terminate;
    fmi2ResetTYPE *reset;
    fmi2SetRealTYPE *setReal;
    fmi2GetRealTYPE *getReal;
    fmi2GetIntegerTYPE *getInteger;
    fmi2SetBooleanTYPE *setBoolean;
    fmi2DoStepTYPE *doStep;
    fmi2CancelStepTYPE *cancelStep;
    fmi2GetFMUstateTYPE *getFMUstate;
    fmi2SetFMUstateTYPE *setFMUstate;
    fmi2FreeFMUstateTYPE *freeFMUstate;
    fmi2SerializedFMUstateSizeTYPE *serializedSize;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
    fmi2SetRealInputDerivativesTYPE *setRealInputDerivatives;
    fmi2GetRealStatusTYPE *getRealStatus;
    fmi2SetDebugLoggingTYPE *setDebugLogging;
} Api;

static void *sym(void *lib, const char *name) {
#ifdef _WIN32
    void *p = (void *)GetProcAddress((HMODULE)lib, name);
#else
    void *p = dlsym(lib, name);
#endif
    if (!p) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(3);
    }
    return p;
}

#define LOAD(field, name) *(void **)(&api->field) = sym(lib, name)

static void load_api(void *lib, Api *api) {
    LOAD(instantiate, "fmi2Instantiate");
    LOAD(freeInstance, "fmi2FreeInstance");
    LOAD(setupExperiment, "fmi2SetupExperiment");
    LOAD(enterInit, "fmi2EnterInitializationMode");
    LOAD(exitInit, "fmi2ExitInitializationMode");
    LOAD(terminate, "fmi2Terminate");
    LOAD(reset, "fmi2Reset");
    LOAD(setReal, "fmi2SetReal");
    LOAD(getReal, "fmi2GetReal");
    LOAD(getInteger, "fmi2GetInteger");
    LOAD(setBoolean, "fmi2SetBoolean");
    LOAD(doStep, "fmi2DoStep");
    LOAD(cancelStep, "fmi2CancelStep");
    LOAD(getFMUstate, "fmi2GetFMUstate");
    LOAD(setFMUstate, "fmi2SetFMUstate");
    LOAD(freeFMUstate, "fmi2FreeFMUstate");
    LOAD(serializedSize, "fmi2SerializedFMUstateSize");
    LOAD(serialize, "fmi2SerializeFMUstate");
    LOAD(deserialize, "fmi2DeSerializeFMUstate");
    LOAD(setRealInputDerivatives, "fmi2SetRealInputDerivatives");
    LOAD(getRealStatus, "fmi2GetRealStatus");
    LOAD(setDebugLogging, "fmi2SetDebugLogging");
}

static double now_s(void) {
#ifdef _WIN32
    LARGE_INTEGER f, c;
    QueryPerformanceFrequency(&f);
    QueryPerformanceCounter(&c);
    return (double)c.QuadPart / (double)f.QuadPart;
#else
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
#endif
}

static int failures = 0;
#define EXPECT(call, want)                                                              \
    do {                                                                                \
        fmi2Status st_ = (call);                                                        \
        if (st_ != (want)) {                                                            \
            fprintf(stderr, "line %d: %s returned %d, expected %d\n", __LINE__, #call,  \
                    (int)st_, (int)(want));                                             \
            failures++;                                                                 \
        }                                                                               \
    } while (0)

typedef struct {
    int npar;
    fmi2ValueReference *par_vr;
    double *par_val;
} Params;

static fmi2Component start(Api *api, const fmi2CallbackFunctions *cb, const char *guid, const char *name,
                           const Params *P, const fmi2ValueReference *vr_in, int nin, const double *u0) {
    int i;
    fmi2Component c = api->instantiate(name, fmi2CoSimulation, guid, "", cb, fmi2False, fmi2False);
    if (!c) {
        fprintf(stderr, "instantiate failed\n");
        exit(4);
    }
    EXPECT(api->setupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK);
    EXPECT(api->enterInit(c), fmi2OK);
    for (i = 0; i < P->npar; i++) EXPECT(api->setReal(c, &P->par_vr[i], 1, &P->par_val[i]), fmi2OK);
    if (nin) EXPECT(api->setReal(c, vr_in, (size_t)nin, u0), fmi2OK);
    EXPECT(api->exitInit(c), fmi2OK);
    return c;
}

int main(int argc, char **argv) {
    const char *mode, *libpath, *guid, *in_file, *out_file;
    double Ts, *U, *Y, *u;
    long nsteps, k, nout_steps;
    int comm, ninst, nin, nout, i, j, a = 1;
    fmi2ValueReference *vr_in, *vr_out;
    Params P = {0, NULL, NULL};
    void *lib;
    Api api;
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    FILE *f;
    if (argc < 12) {
        fprintf(stderr, "usage: host MODE LIB GUID Ts NSTEPS COMM NINST IN_FILE OUT_FILE NIN NOUT vr_in... "
                        "vr_out... [NPAR vr value ...]\n");
        return 2;
    }
    mode = argv[a++]; libpath = argv[a++]; guid = argv[a++];
    Ts = atof(argv[a++]); nsteps = atol(argv[a++]); comm = atoi(argv[a++]); ninst = atoi(argv[a++]);
    in_file = argv[a++]; out_file = argv[a++]; nin = atoi(argv[a++]); nout = atoi(argv[a++]);
    if (argc < a + nin + nout) return 2;
    vr_in = (fmi2ValueReference *)calloc((size_t)nin + 1, sizeof *vr_in);
    vr_out = (fmi2ValueReference *)calloc((size_t)nout + 1, sizeof *vr_out);
    for (i = 0; i < nin; i++) vr_in[i] = (fmi2ValueReference)atol(argv[a++]);
    for (i = 0; i < nout; i++) vr_out[i] = (fmi2ValueReference)atol(argv[a++]);
    if (a < argc) {
        P.npar = atoi(argv[a++]);
        P.par_vr = (fmi2ValueReference *)calloc((size_t)P.npar + 1, sizeof *P.par_vr);
        P.par_val = (double *)calloc((size_t)P.npar + 1, sizeof *P.par_val);
        for (i = 0; i < P.npar && a + 1 < argc; i++) {
            P.par_vr[i] = (fmi2ValueReference)atol(argv[a++]);
            P.par_val[i] = atof(argv[a++]);
        }
    }
    quiet = strcmp(mode, "errors") == 0;
#ifdef _WIN32
    lib = (void *)LoadLibraryA(libpath);
#else
    lib = dlopen(libpath, RTLD_NOW | RTLD_LOCAL);
#endif
    if (!lib) {
        fprintf(stderr, "cannot load %s\n", libpath);
        return 3;
    }
    load_api(lib, &api);
    U = (double *)calloc((size_t)(nsteps * nin) + 1, sizeof(double));
    f = fopen(in_file, "rb");
    if (!f || fread(U, sizeof(double), (size_t)(nsteps * nin), f) != (size_t)(nsteps * nin)) {
        fprintf(stderr, "cannot read %s\n", in_file);
        return 3;
    }
    fclose(f);
    nout_steps = nsteps / comm;
    u = (double *)calloc((size_t)nin + 1, sizeof(double));

    if (strcmp(mode, "run") == 0) {
        fmi2Component *c = (fmi2Component *)calloc((size_t)ninst, sizeof *c);
        char name[32];
        Y = (double *)calloc((size_t)(ninst * nout_steps * nout) + 1, sizeof(double));
        for (i = 0; i < ninst; i++) {
            for (j = 0; j < nin; j++) u[j] = U[j] * (1.0 + 0.25 * i);
            sprintf(name, "inst%d", i);
            c[i] = start(&api, &cb, guid, name, &P, vr_in, nin, u);
        }
        for (k = 0; k < nout_steps; k++) {
            for (i = 0; i < ninst; i++) {
                for (j = 0; j < nin; j++) u[j] = U[k * comm * nin + j] * (1.0 + 0.25 * i);
                if (nin) EXPECT(api.setReal(c[i], vr_in, (size_t)nin, u), fmi2OK);
                EXPECT(api.getReal(c[i], vr_out, (size_t)nout, Y + ((long)i * nout_steps + k) * nout), fmi2OK);
                EXPECT(api.doStep(c[i], (double)(k * comm) * Ts, comm * Ts, fmi2True), fmi2OK);
            }
        }
        for (i = 0; i < ninst; i++) {
            EXPECT(api.terminate(c[i]), fmi2OK);
            api.freeInstance(c[i]);
        }
        f = fopen(out_file, "wb");
        if (!f) return 3;
        fwrite(Y, sizeof(double), (size_t)(ninst * nout_steps * nout), f);
        fclose(f);
        free(Y);
        free(c);
    } else if (strcmp(mode, "bench") == 0) {
        fmi2Component c = start(&api, &cb, guid, "bench", &P, vr_in, nin, U);
        double t0, t1, acc = 0.0;
        Y = (double *)calloc((size_t)nout + 1, sizeof(double));
        t0 = now_s();
        for (k = 0; k < nsteps; k++) {
            if (nin) api.setReal(c, vr_in, (size_t)nin, U + k * nin);
            api.getReal(c, vr_out, (size_t)nout, Y);
            acc += Y[0];
            api.doStep(c, (double)k * Ts, Ts, fmi2True);
        }
        t1 = now_s();
        printf("steps_per_second %.6g\nchecksum %.17g\n", (double)nsteps / (t1 - t0), acc);
        api.terminate(c);
        api.freeInstance(c);
        free(Y);
    } else if (strcmp(mode, "errors") == 0) {
        fmi2Component c;
        fmi2FMUstate s = NULL, s2 = NULL;
        fmi2Real nan = 0.0, y1[64], y2[64], t;
        fmi2ValueReference bad = 1000000;
        fmi2Integer iv;
        size_t size = 0;
        fmi2Byte *buf;
        const char *cats[] = {"logCalls"}, *badcat[] = {"noSuchCategory"};
        nan = nan / nan;
        memset(y1, 0, sizeof y1);
        memset(y2, 0, sizeof y2);
        if (nout > 64) nout = 64;
        /* wrong GUID and wrong type: no instance */
        if (api.instantiate("x", fmi2CoSimulation, "{wrong}", "", &cb, fmi2False, fmi2False)) failures++;
        if (api.instantiate("x", fmi2ModelExchange, guid, "", &cb, fmi2False, fmi2False)) failures++;
        c = api.instantiate("err", fmi2CoSimulation, guid, "", &cb, fmi2False, fmi2False);
        if (!c) return 4;
        EXPECT(api.setDebugLogging(c, fmi2True, 1, cats), fmi2OK);
        EXPECT(api.setDebugLogging(c, fmi2False, 0, NULL), fmi2OK);
        EXPECT(api.setDebugLogging(c, fmi2True, 1, badcat), fmi2Warning);  /* ignored, instance usable */
        /* wrong call order: doStep / exitInit before initialization */
        EXPECT(api.doStep(c, 0.0, Ts, fmi2True), fmi2Error);
        EXPECT(api.reset(c), fmi2OK);
        EXPECT(api.exitInit(c), fmi2Error);
        EXPECT(api.reset(c), fmi2OK);
        api.freeInstance(c);
        c = start(&api, &cb, guid, "err", &P, vr_in, nin, U);
        /* errors that leave the instance usable after fmi2SetFMUstate */
        EXPECT(api.getFMUstate(c, &s), fmi2OK);
        EXPECT(api.setReal(c, vr_in, 1, &nan), fmi2Error);            /* NaN input */
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        EXPECT(api.getReal(c, &bad, 1, y1), fmi2Error);               /* unknown vr */
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        EXPECT(api.getInteger(c, vr_out, 1, &iv), fmi2Error);         /* no Integer variables */
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        EXPECT(api.setReal(c, vr_out, 1, y1), fmi2Error);             /* outputs cannot be set */
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        EXPECT(api.doStep(c, 0.0, 1.5 * Ts, fmi2True), fmi2Error);    /* not a multiple of Ts */
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        EXPECT(api.doStep(c, 0.0, -Ts, fmi2True), fmi2Error);         /* negative step */
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        EXPECT(api.doStep(c, 0.0, nan, fmi2True), fmi2Error);         /* NaN step */
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        EXPECT(api.doStep(c, 5.0, Ts, fmi2True), fmi2Error);          /* wrong time */
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        EXPECT(api.cancelStep(c), fmi2Error);                         /* nothing pending */
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        if (nin) {   /* first derivatives only (linear interpolation within a step) */
            fmi2Integer order2 = 2;
            fmi2Real slope = 1.0;
            EXPECT(api.setRealInputDerivatives(c, vr_in, 1, &order2, &slope), fmi2Error);
            EXPECT(api.setFMUstate(c, s), fmi2OK);
        }
        EXPECT(api.enterInit(c), fmi2Error);                          /* already initialized */
        EXPECT(api.doStep(c, 0.0, Ts, fmi2True), fmi2Error);          /* still in the error state */
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        /* state round trip: step 3, save, step 5 more, restore, step 5 again -> same outputs */
        for (k = 0; k < 3; k++) {
            if (nin) EXPECT(api.setReal(c, vr_in, (size_t)nin, U + k * nin), fmi2OK);
            EXPECT(api.doStep(c, (double)k * Ts, Ts, fmi2True), fmi2OK);
        }
        EXPECT(api.getFMUstate(c, &s), fmi2OK);                       /* overwrite the snapshot */
        EXPECT(api.serializedSize(c, s, &size), fmi2OK);
        buf = (fmi2Byte *)malloc(size);
        EXPECT(api.serialize(c, s, buf, size), fmi2OK);
        EXPECT(api.serialize(c, s, buf, size - 1), fmi2Error);
        EXPECT(api.setFMUstate(c, s), fmi2OK);
        for (k = 3; k < 8; k++) {
            if (nin) EXPECT(api.setReal(c, vr_in, (size_t)nin, U + k * nin), fmi2OK);
            EXPECT(api.doStep(c, (double)k * Ts, Ts, fmi2True), fmi2OK);
        }
        EXPECT(api.getReal(c, vr_out, (size_t)nout, y1), fmi2OK);
        EXPECT(api.deserialize(c, buf, size, &s2), fmi2OK);
        EXPECT(api.setFMUstate(c, s2), fmi2OK);
        EXPECT(api.getRealStatus(c, fmi2LastSuccessfulTime, &t), fmi2OK);
        if (t < 3 * Ts - 1e-12 || t > 3 * Ts + 1e-12) { fprintf(stderr, "time %g after restore\n", t); failures++; }
        for (k = 3; k < 8; k++) {
            if (nin) EXPECT(api.setReal(c, vr_in, (size_t)nin, U + k * nin), fmi2OK);
            EXPECT(api.doStep(c, (double)k * Ts, Ts, fmi2True), fmi2OK);
        }
        EXPECT(api.getReal(c, vr_out, (size_t)nout, y2), fmi2OK);
        for (j = 0; j < nout; j++)
            if (y1[j] != y2[j]) { fprintf(stderr, "state restore differs at output %d\n", j); failures++; }
        buf[0] ^= 0x5a; /* corrupt the GUID */
        EXPECT(api.deserialize(c, buf, size, &s2), fmi2Error);
        free(buf);
        EXPECT(api.reset(c), fmi2OK);
        EXPECT(api.freeFMUstate(c, &s), fmi2OK);
        EXPECT(api.freeFMUstate(c, &s2), fmi2OK);
        if (s || s2) failures++;
        EXPECT(api.terminate(c), fmi2Error);                          /* instantiated: not allowed */
        EXPECT(api.reset(c), fmi2OK);
        api.freeInstance(c);
        api.freeInstance(NULL);
        if (n_error_messages < 10) { fprintf(stderr, "only %d error messages logged\n", n_error_messages); failures++; }
        printf("errors %s (%d failures, %d error messages)\n", failures ? "FAILED" : "ok", failures,
               n_error_messages);
    } else {
        fprintf(stderr, "unknown mode %s\n", mode);
        return 2;
    }
    free(U); free(u); free(vr_in); free(vr_out); free(P.par_vr); free(P.par_val);
#ifdef _WIN32
    FreeLibrary((HMODULE)lib);
#else
    dlclose(lib);
#endif
    return failures ? 1 : 0;
}
