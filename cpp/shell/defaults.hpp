// The bench's defaults shared by every process, once for C++; the Python side
// takes them from the bindings (sc_rt._core.DEFAULT_LCM_URL), so the two
// languages cannot disagree.
#pragma once

// udpm multicast on the LCM default group and port; ttl=0: nothing leaves the machine.
#define SCRT_DEFAULT_LCM_URL "udpm://239.255.76.67:7667?ttl=0"
