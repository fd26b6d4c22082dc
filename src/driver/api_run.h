#pragma once
// api::Run (include/pcr/api.h) for the command line, its first user: the same run, with the
// driver's errors and warnings naming the command line's options ("--model") instead of
// Config's fields ("Config::model (--model)").
#include "driver/option_names.h"
#include "pcr/api.h"

namespace pcr::driver {

// api::Run with the driver's messages naming the options as `names` says (empty: as the command
// line's options; api::Run passes Config's field names).
api::Result RunNamingOptions(const api::Config& config, const api::Source& source,
                             const api::FrameCallback& on_frame, const OptionNames& names);

}  // namespace pcr::driver
