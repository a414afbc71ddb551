// Queries must not be answered from tiles the store found corrupt: the map holds wrong (or no)
// statistics for them. These checks answer DATA_LOSS naming the first such tile instead.
#pragma once

#include <grpcpp/support/status.h>

#include <span>

#include "service_context.h"

namespace bgkmap {

grpc::Status CheckNoCorruptTile(const ServiceContext& ctx, const CellBox& box);
grpc::Status CheckNoCorruptTile(const ServiceContext& ctx, std::span<const CellIndex> cells);

}  // namespace bgkmap
