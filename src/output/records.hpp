// The collect stage's records, by the names the outputs read them.
#pragma once
#include "collect/collection.hpp"

namespace ces::output {

using collect::Collection;
using collect::CollectorTallies;
using collect::Crossing;
using collect::kLossReasons;
using collect::Loss;
using collect::LossReason;

}  // namespace ces::output
