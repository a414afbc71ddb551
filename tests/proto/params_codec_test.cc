#include "bgkmap/proto/params_codec.h"

#include <gtest/gtest.h>

#include "bgkmap/core/map_param_table.h"
#include "support/non_default_params.h"

namespace bgkmap {
namespace {

using google::protobuf::FieldDescriptor;
using testing_support::DifferingKeys;
using testing_support::KeysAtDefault;
using testing_support::NonDefaultParams;

// The codec finds each parameter's field by its key: every key must name a field of its kind.
TEST(ParamsCodecTest, EveryKeyIsAMapParametersFieldOfItsKind) {
  const google::protobuf::Descriptor* d = v1::MapParameters::descriptor();
  for (const MapParamInfo& info : MapParamTable()) {
    const FieldDescriptor* f = d->FindFieldByName(std::string(ProtoFieldName(info.key)));
    ASSERT_NE(f, nullptr) << "admin.proto MapParameters has no field " << info.key;
    switch (info.kind) {
      case MapParamKind::kDouble:
        EXPECT_EQ(f->type(), FieldDescriptor::TYPE_DOUBLE) << info.key;
        EXPECT_FALSE(f->is_repeated()) << info.key;
        break;
      case MapParamKind::kInt:
        EXPECT_EQ(f->type(), FieldDescriptor::TYPE_INT32) << info.key;
        EXPECT_FALSE(f->is_repeated()) << info.key;
        break;
      case MapParamKind::kDouble3:
        EXPECT_EQ(f->type(), FieldDescriptor::TYPE_DOUBLE) << info.key;
        EXPECT_TRUE(f->is_repeated()) << info.key;
        break;
      case MapParamKind::kEnum:
        EXPECT_EQ(f->type(), FieldDescriptor::TYPE_STRING) << info.key;
        EXPECT_FALSE(f->is_repeated()) << info.key;
        break;
    }
  }
  // And no field is left without a parameter.
  EXPECT_EQ(static_cast<size_t>(d->field_count()), MapParamTable().size());
}

TEST(ParamsCodecTest, RoundTripsEveryKeyThroughTheWire) {
  const MapParams p = NonDefaultParams();
  ASSERT_EQ(KeysAtDefault(p), "");
  v1::MapParameters message;
  ToProto(p, &message);
  v1::MapParameters parsed;
  ASSERT_TRUE(parsed.ParseFromString(message.SerializeAsString()));
  EXPECT_EQ(DifferingKeys(FromProto(parsed), p), "");
}

TEST(ParamsCodecTest, WritesTheGeneratedFields) {
  v1::MapParameters message;
  ToProto(NonDefaultParams(), &message);
  EXPECT_EQ(message.kernel_length(), 0.1 + 0.2);
  EXPECT_EQ(message.tile_size(), 32);
  ASSERT_EQ(message.weights_size(), 3);
  EXPECT_EQ(message.weights(1), 0.7);
  EXPECT_EQ(message.observation(), "mean");
  EXPECT_EQ(message.method(), "one-step");
}

TEST(ParamsCodecTest, UnreadableFieldsKeepTheirDefaults) {
  v1::MapParameters message;
  ToProto(NonDefaultParams(), &message);
  message.set_method("bgk-next");
  message.clear_weights();
  const MapParams p = FromProto(message);
  EXPECT_EQ(p.method, MapParams{}.method);
  EXPECT_EQ(p.weights, MapParams{}.weights);
  EXPECT_EQ(p.observation, Observation::kMean);
}

// `lambda` is a Python keyword: its field is prior_weight, whose JSON name stays "lambda".
TEST(ParamsCodecTest, LambdaTravelsAsPriorWeight) {
  EXPECT_EQ(ProtoFieldName("lambda"), "prior_weight");
  EXPECT_EQ(ProtoFieldName("kernel_length"), "kernel_length");
  MapParams p;
  p.lambda = 0.75;
  v1::MapParameters m;
  ToProto(p, &m);
  EXPECT_EQ(m.prior_weight(), 0.75);
  EXPECT_EQ(FromProto(m).lambda, 0.75);
  const FieldDescriptor* f = v1::MapParameters::descriptor()->FindFieldByNumber(3);
  EXPECT_EQ(f->name(), "prior_weight");
  EXPECT_EQ(f->json_name(), "lambda");
}

}  // namespace
}  // namespace bgkmap
