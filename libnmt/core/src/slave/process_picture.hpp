// Private to libnmt core: object 1F70h "Process picture" (CiA DSP 302 §8.3) of a slave node
// whose device file has [DynamicChannels], served from the network variables in its dictionary.
#pragma once

#include "cfg/object_dictionary.hpp"
#include "nmt/slave/local_dictionary.hpp"

namespace nmt::detail {

/// Adds the hooks that serve 1F70h to `dict` when `device` has [DynamicChannels] and the
/// dictionary has 1F70h sub 1 and sub 2; does nothing otherwise. The hooks keep pointers to
/// `dict` and a copy of the segments: `dict` must outlive them (they live in it).
///
/// Sub 1 "selected range": the figure of its layout is missing from our DSP 302 text, which
/// names an "Index" and then a "Data Length"; assumed (MSB first, as CiA draws words): bits
/// 31-16 an index of a segment's range (it selects that whole segment), bits 15-0 the most bytes
/// to transfer (0: the whole segment). A write of an index that is in no segment aborts with
/// 0609 0030 (CiA 301: value range of parameter exceeded); 0 (the default) selects nothing.
/// Sub 2 reads the selected segment's part of the process picture (from its PPOffset, bytes as
/// the variables lie in it, §8.2 offsets; inputs and outputs are two pictures, and every
/// variable of a segment of the same direction that starts in the part is in it, cut at the
/// length), and a write sets
/// every variable that lies wholly inside the bytes written. With nothing selected, sub 2
/// aborts with 0800 0024 (no data available); a write longer than the selected length or the
/// segment aborts with 0607 0012.
void install_process_picture(LocalDictionary& dict, const cfg::DeviceDescription& device);

}  // namespace nmt::detail
