//! The overview's subscription: the shop's broker read into the [`Shop`], connecting again
//! whenever the broker goes away (said once, and once more when it is back). Over TLS the
//! broker's certificate is checked and the overview's own shown as a bridge's are
//! ([`crate::config::telemetry::TelemetrySettings::tls`]); a broker that fails the check or
//! refuses the overview's certificate is a broker away.

use std::sync::Arc;
use std::time::Duration;

use rumqttc::{AsyncClient, Event, MqttOptions, Packet, QoS, TlsConfiguration, Transport};

use super::Shop;
use crate::config::telemetry::{Broker, TlsConfig};

/// How long the overview waits before it connects again.
const RETRY: Duration = Duration::from_secs(1);

/// Follows the broker at `broker` (over TLS with `tls`, logged in as `login`, if given)
/// into `shop`, until the task is dropped.
pub async fn follow(
    shop: Arc<Shop>,
    (broker, tls): (Broker, Option<TlsConfig>),
    login: Option<(String, String)>,
) {
    let mut session = [0u8; 6];
    let _ = getrandom::fill(&mut session);
    let id: String = session.iter().map(|b| format!("{b:02x}")).collect();
    let mut options =
        MqttOptions::new(format!("whirl-shop-{id}"), broker.host.clone(), broker.port);
    options
        .set_keep_alive(Duration::from_secs(10))
        .set_clean_session(true)
        .set_max_packet_size(1 << 20, 1 << 20);
    if let Some((user, password)) = login {
        options.set_credentials(user, password);
    }
    if let Some(tls) = tls {
        options.set_transport(Transport::tls_with_config(TlsConfiguration::Rustls(tls)));
    }
    let (client, mut events) = AsyncClient::new(options, 16);
    let _ = shop.client.set(client.clone());
    let mut away = false;
    loop {
        match events.poll().await {
            Ok(Event::Incoming(Packet::ConnAck(_))) => {
                // A clean session keeps no subscriptions: each connection makes them again.
                for filter in shop.filters() {
                    let _ = client.try_subscribe(filter, QoS::AtLeastOnce);
                }
                if away {
                    tracing::warn!("shop overview: the broker answers again");
                    away = false;
                }
            }
            Ok(Event::Incoming(Packet::Publish(p))) => shop.take(&p.topic, &p.payload),
            Ok(_) => {}
            Err(error) => {
                if !away {
                    tracing::warn!(
                        "shop overview: the broker at {}:{} cannot be reached ({error}); \
                         trying again every {RETRY:?}",
                        broker.host,
                        broker.port
                    );
                    away = true;
                }
                tokio::time::sleep(RETRY).await;
            }
        }
    }
}
