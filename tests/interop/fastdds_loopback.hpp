#pragma once
/// \file fastdds_loopback.hpp
/// A Fast DDS participant on loopback only, as the project's network rule requires of every
/// participant a test starts: built-in transports off, one UDPv4 transport whitelisted to
/// 127.0.0.1, initial peer 127.0.0.1, unicast-only metatraffic and user traffic on 127.0.0.1
/// (no multicast discovery). Shared by the interoperability clients.

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>

namespace stroma_interop {

/// DDS Security (PKI-DH, permissions, AES-GCM-GMAC) with an identity of `stroma security init`,
/// when STROMA_FASTDDS_SECURITY=DIR:NAME is set (DIR the security directory, NAME the identity:
/// DIR/NAME.pem, DIR/NAME_key.pem, DIR/permissions_NAME.p7s).
inline void add_security(eprosima::fastdds::dds::DomainParticipantQos& pq) {
  const char* spec = std::getenv("STROMA_FASTDDS_SECURITY");
  if (!spec || !*spec) return;
  const std::string s(spec);
  const size_t colon = s.rfind(':');
  if (colon == std::string::npos) {
    std::fprintf(stderr, "STROMA_FASTDDS_SECURITY: give DIR:NAME\n");
    std::exit(2);
  }
  const std::string dir = "file://" + s.substr(0, colon) + "/", name = s.substr(colon + 1);
  auto& p = pq.properties().properties();
  p.emplace_back("dds.sec.auth.plugin", "builtin.PKI-DH");
  p.emplace_back("dds.sec.auth.builtin.PKI-DH.identity_ca", dir + "identity_ca.pem");
  p.emplace_back("dds.sec.auth.builtin.PKI-DH.identity_certificate", dir + name + ".pem");
  p.emplace_back("dds.sec.auth.builtin.PKI-DH.private_key", dir + name + "_key.pem");
  p.emplace_back("dds.sec.access.plugin", "builtin.Access-Permissions");
  p.emplace_back("dds.sec.access.builtin.Access-Permissions.permissions_ca", dir + "permissions_ca.pem");
  p.emplace_back("dds.sec.access.builtin.Access-Permissions.governance", dir + "governance.p7s");
  p.emplace_back("dds.sec.access.builtin.Access-Permissions.permissions", dir + "permissions_" + name + ".p7s");
  p.emplace_back("dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC");
}

/// The participant, or exits 1 saying why.
inline eprosima::fastdds::dds::DomainParticipant* loopback_participant(int domain, const char* name) {
  using eprosima::fastrtps::rtps::IPLocator;
  using eprosima::fastrtps::rtps::Locator_t;
  eprosima::fastdds::dds::DomainParticipantQos pq;
  pq.name(name);
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  udp->interfaceWhiteList.push_back("127.0.0.1");
  pq.transport().use_builtin_transports = false;
  pq.transport().user_transports.push_back(udp);
  Locator_t peer, meta, user;
  IPLocator::setIPv4(peer, 127, 0, 0, 1);
  IPLocator::setIPv4(meta, 127, 0, 0, 1);
  IPLocator::setIPv4(user, 127, 0, 0, 1);
  pq.wire_protocol().builtin.initialPeersList.push_back(peer);
  pq.wire_protocol().builtin.metatrafficUnicastLocatorList.push_back(meta);
  pq.wire_protocol().default_unicast_locator_list.push_back(user);
  add_security(pq);
  auto* pp = eprosima::fastdds::dds::DomainParticipantFactory::get_instance()->create_participant(domain, pq);
  if (!pp) {
    std::fprintf(stderr, "cannot create the Fast DDS participant\n");
    std::exit(1);
  }
  return pp;
}

}  // namespace stroma_interop
