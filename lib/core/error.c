/* error.c - error codes, their sentences, the per-thread last error. */
#include <stdlib.h>

#include "core.h"

/* Like errno: per thread, so constructors stay thread-safe. */
static _Thread_local int last_error;

int sc_set_error(int err)
{
    last_error = err;
    return err;
}

SC_API int sc_last_error(void)
{
    return last_error;
}

SC_API const char *sc_strerror(int err)
{
    switch (err) {
    case SC_OK: return "success";
    case SC_EINVAL: return "invalid argument (NULL, NaN, infinite or out of range)";
    case SC_ENOMEM: return "out of memory";
    case SC_EIO: return "file or cluster URL could not be opened or read";
    case SC_EFORMAT: return "file or message is malformed or truncated";
    case SC_ETOOBIG: return "file or mesh exceeds the size limits";
    case SC_ENOTCLOSED: return "mesh is not a closed, consistently outward-oriented surface";
    case SC_EDEGENERATE: return "mesh or point set has no volume (flat, collinear or zero-area)";
    case SC_ERANGE: return "body id or index out of range";
    case SC_ENOTSUP: return "operation not supported for this shape or body";
    case SC_ENOINIT: return "struct was not initialised by its *_default() function";
    case SC_ENOSOLUTION: return "LCP has no solution the solver can find";
    case SC_EMAXITER: return "LCP solver hit its pivot limit";
    case SC_ENUMERIC: return "numerical breakdown (singular pivot or NaN)";
    case SC_EAUTH: return "message failed authentication or was replayed";
    case SC_EPERM: return "key file is accessible by others: its mode must be 0600";
    case SC_ETOOMANY: return "an island has more contact rows than the exact solver takes (bodies overlap heavily?)";
    case SC_ELIMIT: return "value is finite but outside what the engine simulates (size, position, speed, mass or frame length)";
    default: return "unknown error code";
    }
}

void *sc_alloc_array(size_t n, size_t size)
{
    if (size && n > SIZE_MAX / size)
        return NULL;
    return malloc(n && size ? n * size : 1);
}

int sc_grow(void **p, int *cap, int need, size_t size, int max)
{
    if (need <= *cap)
        return SC_OK;
    if (need > max)
        return SC_ETOOBIG;
    int c = *cap > 0 ? *cap : 64;
    while (c < need)
        c = c > max / 2 ? max : 2 * c;
    void *q = realloc(*p, (size_t)c * size);
    if (!q)
        return SC_ENOMEM;
    *p = q;
    *cap = c;
    return SC_OK;
}

void *sc_calloc_array(size_t n, size_t size)
{
    if (size && n > SIZE_MAX / size)
        return NULL;
    return calloc(n ? n : 1, size ? size : 1);
}
