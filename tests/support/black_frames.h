#pragma once
// A blackout in a dataset (a tunnel, glare, a covered lens): frames shown black on every camera.
#include <cstddef>

#include "io/dataset.h"

namespace pcr::test {

// Frames [first, end) of d read one black image of d's size (written once into a fresh
// MakeTempDir) on the left and, where d has them, the right camera; a test failure when the image
// cannot be written.
void BlackOut(Dataset* d, size_t first, size_t end);

}  // namespace pcr::test
