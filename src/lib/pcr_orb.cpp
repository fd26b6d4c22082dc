// libpcr_orb.so: the public API's implementation is src/driver/api.cpp, linked in whole with
// every layer below it. This file checks that the public header stands on its own.
#include "pcr/api.h"
