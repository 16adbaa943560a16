//! The console's HTTP edge: the page, its JSON API and the server-sent events, on axum.
//!
//! Reading is open to whoever reaches the console; every action (plan, verify, run, hold,
//! resume, stop, the feed override) needs the token when the console has one, in the `X-Whirl-Token` header
//! or the cookie the login form sets (`SameSite=Strict`, `HttpOnly`). Actions take JSON
//! only, which a page of another site cannot post without the browser asking first.

use super::registry::{FeedAsk, FeedError, RunView};
use super::runner::{Console, RunRequest, StartError};
use super::token;
use crate::records::NoteKind;
use crate::transport::control::FeedOverrideError;
use crate::transport::Command;
use axum::extract::{Path, Query, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{Html, IntoResponse, Redirect, Response};
use axum::routing::{get, post};
use axum::{Form, Json, Router};
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

/// The page: HTML, style and script, embedded in the binary.
const INDEX: &str = include_str!("page/index.html");
const STYLE: &str = include_str!("page/style.css");
const SCRIPT: &str = include_str!("page/app.js");
const LOGIN: &str = include_str!("page/login.html");

/// The least time between two events to one page: a run's progress changes far more often
/// than a page needs to redraw.
const EVENT_GAP: Duration = Duration::from_millis(150);

/// The console's routes.
pub fn router(console: Arc<Console>) -> Router {
    Router::new()
        .route("/", get(|| async { Html(INDEX) }))
        .route(
            "/style.css",
            get(|| async { ([(header::CONTENT_TYPE, "text/css")], STYLE) }),
        )
        .route(
            "/app.js",
            get(|| async { ([(header::CONTENT_TYPE, "text/javascript")], SCRIPT) }),
        )
        .route("/login", get(|| async { Html(LOGIN) }).post(login))
        .route("/api/session", get(session))
        .route("/api/machines", get(machines))
        .route("/api/jobs", get(jobs))
        .route("/api/plan", post(plan))
        .route("/api/verify", post(verify))
        .route("/api/runs", get(runs).post(start))
        .route("/api/runs/{machine}/feed-override", post(feed_override))
        .route("/api/runs/{machine}/{button}", post(press))
        .route("/api/runs/{machine}/groove.svg", get(groove))
        .route("/api/history", get(super::history::list))
        .route("/api/history/{id}", get(super::history::show))
        .route("/api/events", get(events))
        .layer(axum::middleware::from_fn_with_state(
            Arc::clone(&console),
            guard,
        ))
        .with_state(console)
}

/// Every action of the API (anything but a read) needs the token, checked before the
/// request is read any further; so does one run's record, which holds the job and machine
/// files it ran (a command-line run's job may lie outside `--jobs`, and a shop's database
/// holds every machine's).
async fn guard(
    State(console): State<Arc<Console>>,
    request: axum::extract::Request,
    next: axum::middleware::Next,
) -> Response {
    let path = request.uri().path();
    let action = request.method() != axum::http::Method::GET && path.starts_with("/api/");
    let files = path.starts_with("/api/history/");
    if action || files {
        if let Err(refused) = authorised(&console, request.headers()) {
            return refused.into_response();
        }
    }
    next.run(request).await
}

/// An error as the API answers it: a status and `{"error": "…"}`.
pub(super) struct ApiError(pub(super) StatusCode, pub(super) String);

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.0, Json(serde_json::json!({ "error": self.1 }))).into_response()
    }
}

impl From<StartError> for ApiError {
    fn from(error: StartError) -> ApiError {
        let status = match &error {
            StartError::UnknownMachine(_) | StartError::NothingToResume(_) => StatusCode::NOT_FOUND,
            StartError::Path(_) => StatusCode::BAD_REQUEST,
            StartError::Run(_) | StartError::Lock(_) => StatusCode::CONFLICT,
            StartError::Thread(_) => StatusCode::INTERNAL_SERVER_ERROR,
            StartError::Record(_) => StatusCode::SERVICE_UNAVAILABLE,
            _ => StatusCode::UNPROCESSABLE_ENTITY,
        };
        ApiError(status, error.to_string())
    }
}

/// Refuses a request without the console's token, when it has one.
fn authorised(console: &Console, headers: &HeaderMap) -> Result<(), ApiError> {
    let Some(expected) = &console.token else {
        return Ok(());
    };
    let value = |name| headers.get(name).and_then(|v| v.to_str().ok());
    let given = token::presented(
        value(token::HEADER),
        value(header::AUTHORIZATION.as_str()),
        value(header::COOKIE.as_str()),
    );
    if given.is_some_and(|g| expected.matches(g)) {
        Ok(())
    } else {
        Err(ApiError(
            StatusCode::UNAUTHORIZED,
            "this console needs its access token for that: log in at /login".into(),
        ))
    }
}

#[derive(serde::Deserialize)]
struct LoginForm {
    token: String,
}

/// The login form: the token, if right, as a cookie for the page's requests.
async fn login(State(console): State<Arc<Console>>, Form(form): Form<LoginForm>) -> Response {
    match &console.token {
        Some(expected) if expected.matches(&form.token) => (
            [(
                header::SET_COOKIE,
                format!(
                    "{}={}; Path=/; HttpOnly; SameSite=Strict",
                    token::COOKIE,
                    expected.as_str()
                ),
            )],
            Redirect::to("/"),
        )
            .into_response(),
        Some(_) => (
            StatusCode::UNAUTHORIZED,
            Html(LOGIN.replace("<!--wrong-->", "<p class=\"alarm\">Wrong token.</p>")),
        )
            .into_response(),
        None => Redirect::to("/").into_response(),
    }
}

/// Whether this page may act: no token needed, or it presented the right one.
async fn session(
    State(console): State<Arc<Console>>,
    headers: HeaderMap,
) -> Json<serde_json::Value> {
    Json(serde_json::json!({
        "token_required": console.token.is_some(),
        "authorised": authorised(&console, &headers).is_ok(),
    }))
}

async fn machines(State(console): State<Arc<Console>>) -> Json<Vec<String>> {
    Json(console.machines.keys().cloned().collect())
}

async fn jobs(State(console): State<Arc<Console>>) -> Json<Vec<String>> {
    Json(console.jobs.list())
}

#[derive(serde::Deserialize)]
struct JobOnMachine {
    job: String,
    machine: String,
}

/// Runs `work` (planning, measuring: seconds of CPU) off the server's thread.
async fn blocking<T: Send + 'static>(
    work: impl FnOnce() -> Result<T, StartError> + Send + 'static,
) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(work)
        .await
        .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
        .map_err(ApiError::from)
}

async fn plan(
    State(console): State<Arc<Console>>,
    Json(request): Json<JobOnMachine>,
) -> Result<Json<serde_json::Value>, ApiError> {
    blocking(move || console.plan(&request.job, &request.machine))
        .await
        .map(Json)
}

async fn verify(
    State(console): State<Arc<Console>>,
    Json(request): Json<JobOnMachine>,
) -> Result<Json<serde_json::Value>, ApiError> {
    blocking(move || console.verify(&request.job, &request.machine))
        .await
        .map(Json)
}

async fn runs(State(console): State<Arc<Console>>) -> Json<Vec<RunView>> {
    Json(console.registry.views())
}

async fn start(
    State(console): State<Arc<Console>>,
    Json(request): Json<RunRequest>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let id = blocking(move || console.start(&request)).await?;
    Ok(Json(serde_json::json!({ "id": id })))
}

/// Hold, resume, stop, or resume a stopped run where it stopped (`resume-at`).
async fn press(
    State(console): State<Arc<Console>>,
    Path((machine, button)): Path<(String, String)>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let command = match button.as_str() {
        "hold" => Command::Hold,
        "resume" => Command::Resume,
        "stop" => Command::Stop {
            reason: "the console's stop button",
        },
        "resume-at" => {
            let id = blocking(move || console.resume(&machine)).await?;
            return Ok(Json(serde_json::json!({ "id": id })));
        }
        other => {
            return Err(ApiError(
                StatusCode::NOT_FOUND,
                format!("no button \"{other}\": hold, resume, stop or resume-at"),
            ))
        }
    };
    console
        .registry
        .press(&machine, command)
        .map_err(|e| ApiError(StatusCode::CONFLICT, e.to_string()))?;
    let noted = match command {
        Command::Hold => Some(NoteKind::Hold),
        Command::Resume => Some(NoteKind::Resume),
        _ => None,
    };
    if let Some(kind) = noted {
        if let Err(error) = console.note_pressed(&machine, kind).await {
            if let Some(view) = console
                .registry
                .views()
                .into_iter()
                .find(|v| v.machine == machine)
            {
                console.registry.update(&machine, view.id, |v| {
                    v.message(format!("the {kind} is not in the run's record: {error}"))
                });
            }
        }
    }
    Ok(Json(serde_json::json!({ "pressed": button })))
}

/// A feed override for `machine`'s run (`{"percent": N}`, or `{"step": ±N}` as the keys of
/// `whirl stream`): refused with the cap and its reason above the cap, below the
/// controller's range, and without a run.
async fn feed_override(
    State(console): State<Arc<Console>>,
    Path(machine): Path<String>,
    Json(ask): Json<FeedAsk>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let (percent, held) = console
        .registry
        .feed_override(&machine, ask)
        .map_err(|error| {
            let status = match &error {
                FeedError::Run(_) | FeedError::Refused(FeedOverrideError::Ended) => {
                    StatusCode::CONFLICT
                }
                FeedError::Refused(_) => StatusCode::UNPROCESSABLE_ENTITY,
            };
            ApiError(status, error.to_string())
        })?;
    Ok(Json(
        serde_json::json!({ "percent": percent, "held": held }),
    ))
}

/// The groove `machine`'s runs have cut so far, as SVG.
async fn groove(
    State(console): State<Arc<Console>>,
    Path(machine): Path<String>,
    Query(_): Query<std::collections::HashMap<String, String>>,
) -> Result<Response, ApiError> {
    let svg = blocking(move || Ok(console.cut_section(&machine)?.map(|p| p.to_svg()))).await?;
    Ok(match svg {
        Some(svg) => ([(header::CONTENT_TYPE, "image/svg+xml")], svg).into_response(),
        None => StatusCode::NO_CONTENT.into_response(),
    })
}

/// Every change of the runs, as server-sent events: the views now, then again after each
/// change, at most one event per [`EVENT_GAP`].
async fn events(
    State(console): State<Arc<Console>>,
) -> Sse<impl futures_util::Stream<Item = Result<Event, Infallible>>> {
    let changes = console.registry.subscribe();
    let stream = futures_util::stream::unfold(
        (console, changes, true),
        |(console, mut changes, first)| async move {
            if !first {
                changes.changed().await.ok()?;
                tokio::time::sleep(EVENT_GAP).await;
            }
            changes.borrow_and_update();
            let views =
                serde_json::to_string(&console.registry.views()).expect("run views serialise");
            Some((
                Ok(Event::default().event("runs").data(views)),
                (console, changes, false),
            ))
        },
    );
    Sse::new(stream).keep_alive(KeepAlive::default())
}
