#include "max_merge_operator.h"

#include <algorithm>

#include "store_keys.h"

namespace bgkmap::storage {

bool MaxMergeOperator::Merge(const rocksdb::Slice& /*key*/, const rocksdb::Slice* existing_value,
                             const rocksdb::Slice& value, std::string* new_value,
                             rocksdb::Logger* /*logger*/) const {
  uint64_t operand, existing = 0;
  if (!ParseU64Bytes(value.ToStringView(), &operand)) return false;
  if (existing_value && !ParseU64Bytes(existing_value->ToStringView(), &existing)) return false;
  *new_value = U64Bytes(std::max(operand, existing));
  return true;
}

}  // namespace bgkmap::storage
