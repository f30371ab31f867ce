// The id of a start a test expects to happen (engine.hpp rule 5: a start that cannot happen
// returns cfg::Result<Id> with the reason). A refused start fails the test and gives Id{}, so
// the test goes on to report what else differs.
#pragma once

#include <gtest/gtest.h>

#include "cfg/result.hpp"

namespace test_support {

template <class Id>
Id started(const cfg::Result<Id>& id) {
  EXPECT_TRUE(id.ok()) << "could not start: " << id.error().message;
  return id.ok() ? *id : Id{};
}

}  // namespace test_support
