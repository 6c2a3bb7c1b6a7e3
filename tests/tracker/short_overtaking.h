// The short overtaking the tracker tests share: heldout/overtaking.toml's
// two vessels over 100 s, the slow one from x = -40 m, the fast one from
// x = -65 m (HarbourScenario.*Overtaking*, the checkpoint before the start
// beside a track, PairBeside's start time). Looked at when the overtaking
// was built (not blind); fresh_overtaking*/ are the blind checks.
#pragma once

#include <string>

#include "magnav/cli/scenario_file.h"
#include "magnav/core/simulate.h"
#include "test_data.h"

namespace magnav::testing {

inline FieldScenario ShortOvertaking() {
  FieldScenario sc = cli::ReadScenarioFile(TestDataDir() + "/generated/scenarios/heldout/overtaking.toml");
  sc.vessels[0].start_position.x() = -40.0;
  sc.vessels[0].segments = {{100.0, 0.0}};
  sc.vessels[1].start_position.x() = -65.0;
  sc.vessels[1].segments = {{100.0, 0.0}};
  return sc;
}

}  // namespace magnav::testing
