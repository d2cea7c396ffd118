// stratum/stratum.hpp -- every stratum module. Each header also compiles on its own; include only
// the one you need (e.g. <stratum/dipole.hpp>) to pull in nothing else.
#pragma once

#include "fresnel.hpp"
#include "quadrature.hpp"
#include "vec3.hpp"
