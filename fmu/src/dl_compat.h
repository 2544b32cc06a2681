/* Bind the dl* functions to their oldest x86-64 versions, so the binary loads on glibc < 2.34 too
 * (glibc 2.34 moved them into libc under a new version; the old ones are still exported).
 * Included by every source of the stub that calls them. */
#ifndef PYFMU_DL_COMPAT_H
#define PYFMU_DL_COMPAT_H
#if defined(__x86_64__) && defined(__GLIBC__)
__asm__(".symver dlopen,dlopen@GLIBC_2.2.5");
__asm__(".symver dlsym,dlsym@GLIBC_2.2.5");
__asm__(".symver dlerror,dlerror@GLIBC_2.2.5");
__asm__(".symver dladdr,dladdr@GLIBC_2.2.5");
#endif
#endif
