#include "lattice/lattice.hpp"

#include <gtest/gtest.h>

TEST(Lattice, Placeholder) {
  EXPECT_EQ(ldem::Lattice(2, 2, 2, 1.0).num_centres(), 8u);
}
