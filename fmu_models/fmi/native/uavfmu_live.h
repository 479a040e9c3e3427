/* uavfmu_live.h: the live handles (instances) of one FMU binary, shared by the native FMI layer
 * (uavfmu_core.h) and the pythonfmu guard (fmu_models/fmi/shim.py).
 *
 * A handle the importer passes is looked up here by address before anything is read through it, so a pointer
 * never handed out, or freed (until the allocator hands the same address to a new instance), is refused
 * without being dereferenced. Slots are claimed and released with atomic compare-and-swap: instances may live
 * in different threads (FMI 2.0.4 section 2.1.3, FMI 3.0 section 2.2.1). At most UAV_MAX_INSTANCES handles
 * are live at once. C11 atomics; MSVC (cl) uses its interlocked intrinsics instead. */
#ifndef UAVFMU_LIVE_H
#define UAVFMU_LIVE_H

#include <stddef.h>

#define UAV_MAX_INSTANCES 4096

#if defined(_MSC_VER) && !defined(__clang__)
#include <intrin.h>
typedef void* volatile uav_live_slot;
typedef long volatile uav_live_count;
/* volatile accesses are acquire / release under MSVC's default /volatile:ms */
static inline void* uav_live_load(uav_live_slot* p) { return *p; }
static inline int uav_live_cas(uav_live_slot* p, void* expected, void* desired) {
    return _InterlockedCompareExchangePointer((void* volatile*)p, desired, expected) == expected;
}
static inline long uav_live_top_load(uav_live_count* p) { return *p; }
static inline int uav_live_top_cas(uav_live_count* p, long expected, long desired) {
    return _InterlockedCompareExchange(p, desired, expected) == expected;
}
#else
#include <stdatomic.h>
typedef _Atomic(void*) uav_live_slot;
typedef atomic_long uav_live_count;
static inline void* uav_live_load(uav_live_slot* p) { return atomic_load(p); }
static inline int uav_live_cas(uav_live_slot* p, void* expected, void* desired) {
    return atomic_compare_exchange_strong(p, &expected, desired);
}
static inline long uav_live_top_load(uav_live_count* p) { return atomic_load(p); }
static inline int uav_live_top_cas(uav_live_count* p, long expected, long desired) {
    return atomic_compare_exchange_strong(p, &expected, desired);
}
#endif

static uav_live_slot uav_live[UAV_MAX_INSTANCES];
static uav_live_count uav_live_top; /* slots at and above this were never used */

/* Claims a slot for handle h: its index, or -1 when UAV_MAX_INSTANCES handles are live. */
static inline int uav_live_add(void* h) {
    for (long i = 0; i < UAV_MAX_INSTANCES; ++i) {
        if (uav_live_load(&uav_live[i]) == NULL && uav_live_cas(&uav_live[i], NULL, h)) {
            long top = uav_live_top_load(&uav_live_top);
            while (top < i + 1 && !uav_live_top_cas(&uav_live_top, top, i + 1)) top = uav_live_top_load(&uav_live_top);
            return (int)i;
        }
    }
    return -1;
}

/* The slot of live handle h, or -1 (NULL, never handed out, or freed). Compares addresses only. */
static inline int uav_live_find(const void* h) {
    if (!h) return -1;
    long top = uav_live_top_load(&uav_live_top);
    for (long i = 0; i < top; ++i)
        if (uav_live_load(&uav_live[i]) == h) return (int)i;
    return -1;
}

/* Releases slot i of handle h (from uav_live_add or uav_live_find). */
static inline void uav_live_remove(int i, void* h) {
    if (i >= 0 && i < UAV_MAX_INSTANCES) uav_live_cas(&uav_live[i], h, NULL);
}

/* 1 when no handle is live. */
static inline int uav_live_none(void) {
    long top = uav_live_top_load(&uav_live_top);
    for (long i = 0; i < top; ++i)
        if (uav_live_load(&uav_live[i]) != NULL) return 0;
    return 1;
}

#endif
