// Private to libcfg: order_for_download for a caller that gives its writes up (the DCF -> writes
// stage of concise_dcf.cpp): they are moved into the result instead of copied, one allocation
// fewer per write (a DCF holds tens of thousands of writes).
#pragma once

#include <vector>

#include "cfg/download_order.hpp"

namespace cfg::detail {

/// order_for_download(writes, current_cob_id), moving the writes; `writes` is left with
/// moved-from entries.
DownloadOrder order_for_download_moving(std::vector<ObjectWrite>&& writes,
                                        const CobIdLookup& current_cob_id);

}  // namespace cfg::detail
