/* A stand-in for Windows' bcryptprimitives.dll, which wine 8 lacks and Rust's
 * std imports ProcessPrng from (every Windows 10/11 has it). scripts/win64.sh
 * builds it with mingw and installs it into the system32 of the test-only wine
 * prefix; it is never part of the FMU. ProcessPrng fills the buffer from
 * RtlGenRandom (advapi32's SystemFunction036), which wine has. */
#include <windows.h>

BOOLEAN WINAPI SystemFunction036(PVOID buffer, ULONG length);

__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length)
{
    while (length > 0) {
        ULONG chunk = length > 0x40000000 ? 0x40000000 : (ULONG)length;
        if (!SystemFunction036(data, chunk))
            return FALSE;
        data += chunk;
        length -= chunk;
    }
    return TRUE;
}
