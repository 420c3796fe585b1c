/*
 * twin_lti.c - the generic FMU runtime of a linear rotor model: one translation unit of the model core
 * (twin_core.c) and the FMI 2.0 and FMI 3.0 APIs on it (twin_fmi2.c, twin_fmi3.c).
 *
 * The binary does not depend on the model (the system comes from resources/twin_lti.bin), so it is compiled
 * once per platform and serves every export, FMI 2.0 and 3.0 alike. Compiled from an FMU's sources/ with a
 * function prefix (-DFMI2_FUNCTION_PREFIX=... or -DFMI3_FUNCTION_PREFIX=...), it builds the API of that
 * version only, so that prefixed builds of several FMUs link side by side; -DTWIN_FMI=2 or 3 chooses one
 * without a prefix.
 */
#if !defined(TWIN_FMI) && defined(FMI2_FUNCTION_PREFIX)
#define TWIN_FMI 2
#endif
#if !defined(TWIN_FMI) && defined(FMI3_FUNCTION_PREFIX)
#define TWIN_FMI 3
#endif

#include "twin_core.c"

#if !defined(TWIN_FMI) || TWIN_FMI == 2
#include "twin_fmi2.c"
#endif
#if !defined(TWIN_FMI) || TWIN_FMI == 3
#include "twin_fmi3.c"
#endif
