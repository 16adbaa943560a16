//! The overview's routes: its page, the machines as JSON and as server-sent events, and the
//! shop's history (the console's own history API, over the shared run records). Every
//! request goes through the console's gate ([`crate::console::http`]): its one action, a
//! Hold on a running machine, needs the page's key and the token, as the console's do.

use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::Path;
use axum::http::{header, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::Html;
use axum::routing::{get, post};
use axum::{Extension, Json, Router};

use super::view::MachineRow;
use super::{HoldError, Shop};
use crate::console::http::{guard, login, login_page, session, ApiError, Client, Edge};
use crate::console::{history, Console};

const PAGE: &str = include_str!("../page/shop.html");
const SCRIPT: &str = include_str!("../page/shop.js");
const STYLE: &str = include_str!("../page/style.css");

/// The least time between two updates to one page: the machines change far more often
/// together than a page needs to redraw, and a change waits at most this.
const EVENT_GAP: Duration = Duration::from_millis(100);

/// The overview's routes; `console` holds the run records its history reads.
pub fn router(shop: Arc<Shop>, console: Arc<Console>, edge: Arc<Edge>) -> Router {
    Router::new()
        .route("/", get(|| async { Html(PAGE) }))
        .route(
            "/style.css",
            get(|| async { ([(header::CONTENT_TYPE, "text/css")], STYLE) }),
        )
        .route(
            "/shop.js",
            get(|| async { ([(header::CONTENT_TYPE, "text/javascript")], SCRIPT) }),
        )
        .route("/login", get(login_page).post(login))
        .route("/api/session", get(session))
        .route("/api/shop", get(rows))
        .route("/api/shop/{machine}/hold", post(hold))
        .route("/api/shop/events", get(events))
        .route("/api/history", get(history::list))
        .route("/api/history/{id}", get(history::show))
        .layer(axum::middleware::from_fn_with_state(
            Arc::clone(&edge),
            guard,
        ))
        .layer(Extension(edge))
        .layer(Extension(shop))
        .with_state(console)
}

async fn rows(Extension(shop): Extension<Arc<Shop>>) -> Json<Vec<MachineRow>> {
    Json(shop.rows())
}

/// The machines at once, then again after every change (at most one each [`EVENT_GAP`]).
/// A Hold to a running machine's bridge (202: sent; the page shows whether it held).
async fn hold(
    Extension(shop): Extension<Arc<Shop>>,
    Extension(client): Extension<Client>,
    Path(machine): Path<String>,
) -> Result<(StatusCode, Json<serde_json::Value>), ApiError> {
    shop.hold(&machine, &client.0).map_err(|e| {
        let status = match e {
            HoldError::Unknown(_) => StatusCode::NOT_FOUND,
            HoldError::NotRunning(..) => StatusCode::CONFLICT,
            HoldError::NoToken | HoldError::Broker(_) => StatusCode::SERVICE_UNAVAILABLE,
        };
        ApiError(status, e.to_string())
    })?;
    tracing::warn!("shop overview: a Hold sent to {machine} for {}", client.0);
    Ok((
        StatusCode::ACCEPTED,
        Json(serde_json::json!({ "sent": "hold" })),
    ))
}

/// The stream ends when the overview does ([`Edge::close`]), so that its server can.
async fn events(
    Extension(shop): Extension<Arc<Shop>>,
    Extension(edge): Extension<Arc<Edge>>,
) -> Sse<impl futures_util::Stream<Item = Result<Event, Infallible>>> {
    let changes = shop.subscribe();
    let closing = edge.closing();
    let stream =
        futures_util::stream::unfold(Some((shop, changes, closing, true)), |state| async move {
            let (shop, mut changes, mut closing, first) = state?;
            if !first {
                tokio::select! {
                    changed = changes.changed() => changed.ok()?,
                    _ = closing.wait_for(|&ended| ended) => return None,
                }
                tokio::time::sleep(EVENT_GAP).await;
            }
            changes.borrow_and_update();
            let rows = serde_json::to_string(&shop.rows()).expect("rows serialise");
            Some((
                Ok(Event::default().event("machines").data(rows)),
                Some((shop, changes, closing, false)),
            ))
        });
    Sse::new(stream).keep_alive(KeepAlive::default())
}
