#include "common/transport/dds.h"

namespace mapmesh::transport {

DdsError::DdsError(const std::string& what, dds_return_t rc)
    : std::runtime_error(what + ": " + dds_strretcode(rc)), rc_(rc) {}

dds_return_t Check(dds_return_t rc, const char* what) {
  if (rc < 0) throw DdsError(what, rc);
  return rc;
}

void Entity::Reset() {
  if (e_ > 0) dds_delete(e_);  // a failure here (already deleted with its parent) is harmless
  e_ = 0;
}

Qos::Qos() : q_(dds_create_qos()) {
  if (!q_) throw std::bad_alloc();
}
Qos::~Qos() { dds_delete_qos(q_); }
Qos::Qos(const Qos& o) : q_(dds_create_qos()) {
  if (!q_) throw std::bad_alloc();
  Check(dds_copy_qos(q_, o.q_), "dds_copy_qos");
}
Qos& Qos::operator=(const Qos& o) {
  if (this != &o) Check(dds_copy_qos(q_, o.q_), "dds_copy_qos");
  return *this;
}
Qos& Qos::Reliable(double max_blocking_s) {
  dds_qset_reliability(q_, DDS_RELIABILITY_RELIABLE, ToDuration(max_blocking_s));
  return *this;
}
Qos& Qos::BestEffort() {
  dds_qset_reliability(q_, DDS_RELIABILITY_BEST_EFFORT, 0);
  return *this;
}
Qos& Qos::KeepAll() {
  dds_qset_history(q_, DDS_HISTORY_KEEP_ALL, 0);
  return *this;
}
Qos& Qos::KeepLast(int depth) {
  dds_qset_history(q_, DDS_HISTORY_KEEP_LAST, depth);
  return *this;
}
Qos& Qos::Volatile() {
  dds_qset_durability(q_, DDS_DURABILITY_VOLATILE);
  return *this;
}
Qos& Qos::TransientLocal() {
  dds_qset_durability(q_, DDS_DURABILITY_TRANSIENT_LOCAL);
  return *this;
}
Qos& Qos::Liveliness(double lease_s) {
  dds_qset_liveliness(q_, DDS_LIVELINESS_AUTOMATIC, ToDuration(lease_s));
  return *this;
}
Qos& Qos::NoAutoDispose() {
  dds_qset_writer_data_lifecycle(q_, false);
  return *this;
}

Qos& Qos::Partition(const std::string& name) {
  dds_qset_partition1(q_, name.c_str());
  return *this;
}

Qos& Qos::Partitions(const std::vector<std::string>& names) {
  std::vector<const char*> ps;
  for (const std::string& n : names) ps.push_back(n.c_str());
  dds_qset_partition(q_, static_cast<uint32_t>(ps.size()), ps.data());
  return *this;
}

Domain::Domain(dds_domainid_t id, const std::string& config)
    : Entity(Check(dds_create_domain(id, config.c_str()), "dds_create_domain")) {}

Participant::Participant(dds_domainid_t domain)
    : Entity(Check(dds_create_participant(domain, nullptr, nullptr), "dds_create_participant")) {}

Topic::Topic(const Participant& p, const dds_topic_descriptor_t* desc, const std::string& name, const Qos& qos)
    : Entity(Check(dds_create_topic(p.get(), desc, name.c_str(), qos.get(), nullptr), "dds_create_topic")) {}

RawWriter::RawWriter(const Participant& p, const Topic& t, const Qos& qos)
    : Entity(Check(dds_create_writer(p.get(), t.get(), qos.get(), nullptr), "dds_create_writer")) {}

void RawWriter::Write(const void* sample) const { Check(dds_write(e_, sample), "dds_write"); }

void RawWriter::Unregister(const void* sample) const {
  Check(dds_unregister_instance(e_, sample), "dds_unregister_instance");
}

namespace {
dds_publication_matched_status_t PublicationMatched(dds_entity_t writer) {
  dds_publication_matched_status_t st;
  Check(dds_get_publication_matched_status(writer, &st), "dds_get_publication_matched_status");
  return st;
}
}  // namespace

std::uint32_t RawWriter::MatchedReaders() const { return PublicationMatched(e_).current_count; }

std::uint32_t RawWriter::TotalMatchedReaders() const { return PublicationMatched(e_).total_count; }

bool RawWriter::WaitForAcks(double timeout_s) const {
  const dds_return_t rc = dds_wait_for_acks(e_, ToDuration(timeout_s));
  if (rc == DDS_RETCODE_TIMEOUT) return false;
  Check(rc, "dds_wait_for_acks");
  return true;
}

RawReader::RawReader(const Participant& p, const Topic& t, const Qos& qos)
    : Entity(Check(dds_create_reader(p.get(), t.get(), qos.get(), nullptr), "dds_create_reader")) {}

bool WriterPartitions::Lookup(dds_instance_handle_t publication) {
  dds_builtintopic_endpoint_t* ep = dds_get_matched_publication_data(reader_, publication);
  if (!ep) return false;
  std::vector<std::string> names;
  uint32_t n = 0;
  char** ps = nullptr;
  if (ep->qos && dds_qget_partition(ep->qos, &n, &ps)) {
    for (uint32_t i = 0; i < n; ++i) {
      names.emplace_back(ps[i]);
      dds_free(ps[i]);
    }
    dds_free(ps);
  }
  std::string guid(reinterpret_cast<const char*>(ep->key.v), sizeof(ep->key.v));
  dds_builtintopic_free_endpoint(ep);
  writers_[publication] = {std::move(names), std::move(guid)};
  return true;
}

void WriterPartitions::Refresh() {
  dds_subscription_matched_status_t st;
  if (dds_get_subscription_matched_status(reader_, &st) < 0 || st.total_count == seen_total_) return;
  seen_total_ = st.total_count;
  std::vector<dds_instance_handle_t> handles(st.current_count + 16);
  const dds_return_t n = dds_get_matched_publications(reader_, handles.data(), handles.size());
  for (dds_return_t i = 0; i < n && i < static_cast<dds_return_t>(handles.size()); ++i) {
    if (!writers_.count(handles[i])) Lookup(handles[i]);
  }
}

const WriterPartitions::Writer* WriterPartitions::Find(dds_instance_handle_t publication) {
  Refresh();
  auto it = writers_.find(publication);
  if (it == writers_.end() && Lookup(publication)) it = writers_.find(publication);
  return it == writers_.end() ? nullptr : &it->second;
}

const std::vector<std::string>* WriterPartitions::Of(dds_instance_handle_t publication) {
  const Writer* w = Find(publication);
  return w ? &w->partitions : nullptr;
}

const std::string* WriterPartitions::GuidOf(dds_instance_handle_t publication) {
  const Writer* w = Find(publication);
  return w ? &w->guid : nullptr;
}

GuardCondition::GuardCondition(const Participant& p)
    : Entity(Check(dds_create_guardcondition(p.get()), "dds_create_guardcondition")) {}

void GuardCondition::Trigger() const { Check(dds_set_guardcondition(e_, true), "dds_set_guardcondition"); }

bool GuardCondition::Triggered() const {
  bool t = false;
  Check(dds_read_guardcondition(e_, &t), "dds_read_guardcondition");
  return t;
}

WaitSet::WaitSet(const Participant& p) : Entity(Check(dds_create_waitset(p.get()), "dds_create_waitset")) {}

void WaitSet::AttachReader(const RawReader& r, dds_attach_t tag) {
  Entity cond(Check(dds_create_readcondition(r.get(), DDS_ANY_STATE), "dds_create_readcondition"));
  Check(dds_waitset_attach(e_, cond.get(), tag), "dds_waitset_attach");
  conditions_.push_back(std::move(cond));
}

void WaitSet::AttachGuard(const GuardCondition& g, dds_attach_t tag) {
  Check(dds_waitset_attach(e_, g.get(), tag), "dds_waitset_attach");
}

std::vector<dds_attach_t> WaitSet::Wait(double timeout_s) const {
  dds_attach_t tags[16];
  const dds_return_t n = Check(dds_waitset_wait(e_, tags, 16, ToDuration(timeout_s)), "dds_waitset_wait");
  return std::vector<dds_attach_t>(tags, tags + std::min<dds_return_t>(n, 16));
}

}  // namespace mapmesh::transport
