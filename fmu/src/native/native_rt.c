/*
 * The run-time symbols that the object code of the compiled model functions needs (native FMUs, issue 30;
 * pyfmu_wrapper/fmubuild/native_obj.py emits that object code from the numba source and lists these symbols).
 * No model code is here: only what numba's generated code calls outside itself.
 *
 *  - NRT allocation (np.empty / np.zeros inside the compiled functions): a MemInfo with numba's layout
 *    (reference count, destructor, its argument, data, size, external allocator: the generated code reads
 *    the data pointer and the count at those offsets) followed by the data, aligned as asked.
 *  - The exception path of a numba cfunc wrapper (it takes the GIL, unpickles the exception and prints it
 *    with PyErr_WriteUnraisable): with no Python, every call does nothing and the cfunc returns 0, which
 *    the stub reads as "the compiled function raised" (never OK).
 *
 * Every symbol is hidden: a native FMU loaded into a Python process never binds these names to Python's.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#if defined(_WIN32)
#define RT_HIDDEN
#else
#define RT_HIDDEN __attribute__((visibility("hidden")))
#endif

typedef void (*rt_dtor)(void *data, size_t size, void *info);
typedef struct {
    size_t refct;
    rt_dtor dtor;
    void *dtor_info;
    void *data;
    size_t size;
    void *external_allocator;
} RtMemInfo;

RT_HIDDEN void *NRT_MemInfo_alloc_aligned(size_t size, unsigned align) {
    if (align == 0) align = 1;
    /* one block: the MemInfo, padding up to the alignment, the data; the MemInfo is its start */
    size_t total = sizeof(RtMemInfo) + size + 2 * (size_t)align;
    char *base = malloc(total);
    if (!base) return NULL;
    uintptr_t data = (uintptr_t)(base + sizeof(RtMemInfo));
    uintptr_t rem = data % align;
    if (rem) data += align - rem;
    RtMemInfo *mi = (RtMemInfo *)base;
    mi->refct = 1;
    mi->dtor = NULL;
    mi->dtor_info = NULL;
    mi->data = (void *)data;
    mi->size = size;
    mi->external_allocator = NULL;
    return mi;
}

RT_HIDDEN void NRT_Free(void *ptr) { free(ptr); }

RT_HIDDEN void NRT_MemInfo_call_dtor(void *p) {
    RtMemInfo *mi = (RtMemInfo *)p;
    if (!mi) return;
    if (mi->dtor) mi->dtor(mi->data, mi->size, mi->dtor_info);
    free(mi);
}

/* ---- the exception path of the cfunc wrapper: nothing to do without Python --------------------------- */
static char rt_none_object[64]; /* a non-NULL "object" for the calls that return one */

RT_HIDDEN char PyExc_RuntimeError, PyExc_StopIteration, PyExc_SystemError;
RT_HIDDEN void numba_gil_ensure(void *state) { (void)state; }
RT_HIDDEN void numba_gil_release(void *state) { (void)state; }
RT_HIDDEN void *numba_unpickle(const char *data, int n, const char *hashed) {
    (void)data; (void)n; (void)hashed;
    return rt_none_object;
}
RT_HIDDEN int numba_do_raise(void *exc) { (void)exc; return 0; }
RT_HIDDEN void *numba_runtime_build_excinfo_struct(void *a, void *b) {
    (void)a; (void)b;
    return rt_none_object;
}
RT_HIDDEN void PyErr_WriteUnraisable(void *o) { (void)o; }
RT_HIDDEN void PyErr_SetString(void *t, const char *m) { (void)t; (void)m; }
RT_HIDDEN void PyErr_SetNone(void *t) { (void)t; }
RT_HIDDEN void PyErr_Clear(void) {}
RT_HIDDEN void Py_DecRef(void *o) { (void)o; }
RT_HIDDEN void *PyBytes_FromStringAndSize(const char *s, ptrdiff_t n) {
    (void)s; (void)n;
    return rt_none_object;
}
RT_HIDDEN void *PyUnicode_FromString(const char *s) {
    (void)s;
    return rt_none_object;
}
