#pragma once
// Free ToMsg/FromMsg converters between the core value types (common/types) and the
// IDL-generated C structs, plus Wire<T>, which names each type's topic descriptor.
// ToMsg results may point into the source value (sequences); use them while it lives.

#include "common/types/messages.h"
#include "mapmesh.h"

namespace mapmesh::transport {

template <typename T>
struct Wire;  // Wire<T>::Msg (generated struct) and Wire<T>::Descriptor()

#define MAPMESH_WIRE(Type, MsgType)                                               \
  template <>                                                                     \
  struct Wire<Type> {                                                             \
    using Msg = MsgType;                                                          \
    static const dds_topic_descriptor_t* Descriptor() { return &MsgType##_desc; } \
  }

MAPMESH_WIRE(Odometry, mapmesh_msg_Odometry);
MAPMESH_WIRE(Scan, mapmesh_msg_Scan);
MAPMESH_WIRE(RadioLinks, mapmesh_msg_RadioLinks);
MAPMESH_WIRE(GroundTruth, mapmesh_msg_GroundTruth);
MAPMESH_WIRE(MapMessage, mapmesh_msg_MapMessage);
MAPMESH_WIRE(AgentStatus, mapmesh_msg_AgentStatus);
MAPMESH_WIRE(Sighting, mapmesh_msg_Sighting);
MAPMESH_WIRE(ExchangeTick, mapmesh_msg_ExchangeTick);
#undef MAPMESH_WIRE

// Scratch storage for the sequences of a message being written.
struct MsgScratch {
  std::vector<mapmesh_msg_Observation> obs;
  std::vector<mapmesh_msg_Link> links;
  std::vector<mapmesh_msg_TickPeer> tick_peers;
  std::vector<mapmesh_msg_Sighting> sightings;
  std::vector<mapmesh_msg_SubmapChain> chains;
  std::vector<mapmesh_msg_SubmapBlob> blobs;
  std::vector<mapmesh_msg_ChainPlacement> placements;
  std::vector<std::uint32_t> ids, ids2;
};

mapmesh_msg_Odometry ToMsg(const Odometry& v, MsgScratch& scratch);
mapmesh_msg_Scan ToMsg(const Scan& v, MsgScratch& scratch);
mapmesh_msg_RadioLinks ToMsg(const RadioLinks& v, MsgScratch& scratch);
mapmesh_msg_GroundTruth ToMsg(const GroundTruth& v, MsgScratch& scratch);
mapmesh_msg_MapMessage ToMsg(const MapMessage& v, MsgScratch& scratch);
mapmesh_msg_AgentStatus ToMsg(const AgentStatus& v, MsgScratch& scratch);
mapmesh_msg_Sighting ToMsg(const Sighting& v, MsgScratch& scratch);
mapmesh_msg_ExchangeTick ToMsg(const ExchangeTick& v, MsgScratch& scratch);

Odometry FromMsg(const mapmesh_msg_Odometry& m);
Scan FromMsg(const mapmesh_msg_Scan& m);
RadioLinks FromMsg(const mapmesh_msg_RadioLinks& m);
GroundTruth FromMsg(const mapmesh_msg_GroundTruth& m);
MapMessage FromMsg(const mapmesh_msg_MapMessage& m);
AgentStatus FromMsg(const mapmesh_msg_AgentStatus& m);
Sighting FromMsg(const mapmesh_msg_Sighting& m);
ExchangeTick FromMsg(const mapmesh_msg_ExchangeTick& m);

}  // namespace mapmesh::transport
