//! The console's HTTP edge: the page, its JSON API and the server-sent events, on axum.
//!
//! Every request is first put through the [`Gate`] ([`super::gate`] says why each rule is
//! there): the `Host` must name the console, and a request that acts (anything but `GET`)
//! must come from the console's own page (its `Origin`, and the page key in the
//! [`PAGE_HEADER`]). Reading is then open to whoever reaches the console; every action (plan,
//! verify, run, hold, resume, stop, the feed override) needs the token when the console has
//! one, in the `X-Whirl-Token` header or through the session the login form opens
//! ([`super::login`]). Every answer forbids framing and sniffing. Every refusal is said on
//! the console's standard error with the client's address.

use super::gate::{Gate, Refusal, PAGE_HEADER};
use super::login::{Guesses, Sessions};
use super::registry::{FeedAsk, FeedError, RunView};
use super::runner::{Console, RunRequest, StartError};
use super::token::{self, Token};
use crate::records::NoteKind;
use crate::transport::control::FeedOverrideError;
use crate::transport::Command;
use axum::extract::{ConnectInfo, Path, Query, State};
use axum::http::{header, HeaderMap, HeaderValue, Method, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{Html, IntoResponse, Redirect, Response};
use axum::routing::{get, post};
use axum::{Extension, Form, Json, Router};
use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The page: HTML, style and script, embedded in the binary.
const INDEX: &str = include_str!("page/index.html");
const STYLE: &str = include_str!("page/style.css");
const SCRIPT: &str = include_str!("page/app.js");
const LOGIN: &str = include_str!("page/login.html");

/// The least time between two events to one page: a run's progress changes far more often
/// than a page needs to redraw.
const EVENT_GAP: Duration = Duration::from_millis(150);

/// What the HTTP edge keeps beside the console: its gate, the token, and the login's
/// sessions and wrong guesses.
#[derive(Debug)]
pub struct Edge {
    gate: Gate,
    token: Option<Token>,
    /// The session cookie's name, which carries the console's port.
    cookie: String,
    sessions: Mutex<Sessions>,
    guesses: Mutex<Guesses>,
    /// Set when the console is ending: no action is taken any more.
    ending: std::sync::atomic::AtomicBool,
    /// Set when the console has ended its runs: each page's events say so and end.
    closing: tokio::sync::watch::Sender<bool>,
}

impl Edge {
    /// The edge of a console on `port` with `gate` and `token`.
    pub fn new(gate: Gate, token: Option<Token>, port: u16) -> Edge {
        Edge {
            gate,
            token,
            cookie: token::cookie_name(port),
            sessions: Mutex::default(),
            guesses: Mutex::new(Guesses::new(Instant::now())),
            ending: std::sync::atomic::AtomicBool::new(false),
            closing: tokio::sync::watch::Sender::new(false),
        }
    }

    /// The console is ending: from now on every action is refused (a run started now
    /// would outlive the stop of the others), while the pages still see the runs stop.
    pub fn end_actions(&self) {
        self.ending.store(true, std::sync::atomic::Ordering::SeqCst);
    }

    /// The console is ending (its runs stopped): every page's event stream says so in a
    /// `gone` event and ends, so that the server can.
    pub fn close(&self) {
        self.closing.send_replace(true);
    }

    /// Turns true when [`Edge::close`] is called: an event stream ends on it.
    pub fn closing(&self) -> tokio::sync::watch::Receiver<bool> {
        self.closing.subscribe()
    }
}

/// Who sent a request, for the console's log and the notes of what they pressed: the
/// client's address and, if it logged in, the first digits of its session.
#[derive(Debug, Clone)]
pub(super) struct Client(pub(super) String);

/// The console's routes.
pub fn router(console: Arc<Console>, edge: Arc<Edge>) -> Router {
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
        .route("/login", get(login_page).post(login))
        .route("/api/session", get(session))
        .route("/api/machines", get(machines))
        .route("/api/jobs", get(jobs))
        .route("/api/profile", get(profile))
        .route("/api/plan", post(plan))
        .route("/api/verify", post(verify))
        .route("/api/runs", get(runs).post(start))
        .route("/api/locks", get(locks))
        .route("/api/runs/{machine}/feed-override", post(feed_override))
        .route("/api/runs/{machine}/{button}", post(press))
        .route("/api/runs/{machine}/groove.svg", get(groove))
        .route("/api/history", get(super::history::list))
        .route("/api/history/{id}", get(super::history::show))
        .route("/api/events", get(events))
        .layer(axum::middleware::from_fn_with_state(
            Arc::clone(&edge),
            guard,
        ))
        .layer(Extension(edge))
        .with_state(console)
}

/// Every request through the gate, then every action of the API (anything but a read)
/// needs the token, checked before the request is read any further; so does one run's
/// record, which holds the job and machine files it ran (a command-line run's job may lie
/// outside `--jobs`, and a shop's database holds every machine's). Every answer carries
/// the headers that keep the page out of other sites' frames.
pub(super) async fn guard(
    State(edge): State<Arc<Edge>>,
    mut request: axum::extract::Request,
    next: axum::middleware::Next,
) -> Response {
    let client = client(&edge, &request);
    let checked = checked(&edge, &request);
    let mut response = match checked {
        Ok(()) => {
            request.extensions_mut().insert(client);
            next.run(request).await
        }
        Err(refused) => {
            tracing::warn!(
                "refused {} {} from {}: {}",
                request.method(),
                request.uri().path(),
                client.0,
                refused.1
            );
            refused.into_response()
        }
    };
    let headers = response.headers_mut();
    for (name, value) in SAFETY_HEADERS {
        headers.insert(name, HeaderValue::from_static(value));
    }
    response
}

/// What every answer says of where it may be shown: in no frame (clickjacking: another
/// site framing the console under a decoy to catch the operator's click on Stop), its
/// scripts and styles only its own, its type as sent, no referrer to other sites.
const SAFETY_HEADERS: [(header::HeaderName, &str); 5] = [
    (header::X_FRAME_OPTIONS, "DENY"),
    (
        header::CONTENT_SECURITY_POLICY,
        "default-src 'self'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; \
         frame-ancestors 'none'; form-action 'self'; base-uri 'none'",
    ),
    (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
    // Not `no-referrer`: under it a browser sends `Origin: null` with the page's own forms.
    (header::REFERRER_POLICY, "same-origin"),
    (
        header::HeaderName::from_static("cross-origin-resource-policy"),
        "same-origin",
    ),
];

/// The gate's rules and the token, for one request.
fn checked(edge: &Edge, request: &axum::extract::Request) -> Result<(), ApiError> {
    let headers = request.headers();
    let value = |name: &str| headers.get(name).and_then(|v| v.to_str().ok());
    let refused = |r: Refusal| ApiError(StatusCode::FORBIDDEN, r.to_string());
    edge.gate
        .allows_host(value(header::HOST.as_str()))
        .map_err(refused)?;
    let path = request.uri().path();
    let acts = !matches!(*request.method(), Method::GET | Method::HEAD);
    let (origin, site) = (value(header::ORIGIN.as_str()), value("sec-fetch-site"));
    if acts && path == "/login" {
        // The login form cannot set a header: it carries the page key in a field, which
        // the handler checks.
        edge.gate.allows_origin(origin, site).map_err(refused)?;
    } else if acts {
        edge.gate
            .allows_action(origin, site, value(PAGE_HEADER))
            .map_err(refused)?;
    }
    if (acts && path.starts_with("/api/")) || path.starts_with("/api/history/") {
        authorised(edge, headers)?;
    }
    if acts && edge.ending.load(std::sync::atomic::Ordering::SeqCst) {
        return Err(ApiError(
            StatusCode::SERVICE_UNAVAILABLE,
            "the console is ending: it is stopping its runs".into(),
        ));
    }
    Ok(())
}

/// The request's client in words: its address, and its session's first digits.
fn client(edge: &Edge, request: &axum::extract::Request) -> Client {
    let address = request
        .extensions()
        .get::<ConnectInfo<SocketAddr>>()
        .map_or("an unknown address".to_owned(), |c| c.0.to_string());
    let cookies = request
        .headers()
        .get(header::COOKIE)
        .and_then(|v| v.to_str().ok());
    Client(match token::cookie(cookies, &edge.cookie) {
        Some(id) if lock(&edge.sessions).holds(id) => {
            format!("{address} (session {})", &id[..id.len().min(8)])
        }
        _ => address,
    })
}

fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
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

/// Refuses a request without the console's token, when it has one: the token in a header,
/// or a session the login opened.
fn authorised(edge: &Edge, headers: &HeaderMap) -> Result<(), ApiError> {
    let Some(expected) = &edge.token else {
        return Ok(());
    };
    let value = |name| headers.get(name).and_then(|v| v.to_str().ok());
    let given = token::presented(value(token::HEADER), value(header::AUTHORIZATION.as_str()));
    let session = token::cookie(value(header::COOKIE.as_str()), &edge.cookie);
    if given.is_some_and(|g| expected.matches(g))
        || session.is_some_and(|id| lock(&edge.sessions).holds(id))
    {
        Ok(())
    } else {
        Err(ApiError(
            StatusCode::UNAUTHORIZED,
            "this console needs its access token for that: log in at /login".into(),
        ))
    }
}

/// The login page, with the page key its form posts back.
pub(super) async fn login_page(Extension(edge): Extension<Arc<Edge>>) -> Html<String> {
    Html(login_html(&edge, ""))
}

fn login_html(edge: &Edge, said: &str) -> String {
    LOGIN
        .replace("<!--wrong-->", said)
        .replace("{{page_key}}", edge.gate.key())
}

#[derive(serde::Deserialize)]
pub(super) struct LoginForm {
    token: String,
    /// The page key the login page carries.
    #[serde(default)]
    page: String,
}

/// The login form: the token, if right, opens a session whose random id the cookie holds.
/// Wrong tokens are limited ([`Guesses`]) and each is said on standard error.
pub(super) async fn login(
    Extension(edge): Extension<Arc<Edge>>,
    Extension(client): Extension<Client>,
    Form(form): Form<LoginForm>,
) -> Response {
    let Some(expected) = &edge.token else {
        return Redirect::to("/").into_response();
    };
    if !super::gate::same(&form.page, edge.gate.key()) {
        tracing::warn!("refused a login from {}: {}", client.0, Refusal::NoPageKey);
        return ApiError(StatusCode::FORBIDDEN, Refusal::NoPageKey.to_string()).into_response();
    }
    let now = Instant::now();
    if let Err(wait) = lock(&edge.guesses).allow(now) {
        tracing::warn!("refused a login from {}: too many wrong tokens", client.0);
        let said = format!(
            "<p class=\"alarm\">Too many wrong tokens: try again in {} s.</p>",
            wait.as_secs() + 1
        );
        return (
            StatusCode::TOO_MANY_REQUESTS,
            Html(login_html(&edge, &said)),
        )
            .into_response();
    }
    if !expected.matches(&form.token) {
        lock(&edge.guesses).wrong(now);
        tracing::warn!("a wrong access token from {}", client.0);
        let said = "<p class=\"alarm\">Wrong token.</p>";
        return (StatusCode::UNAUTHORIZED, Html(login_html(&edge, said))).into_response();
    }
    let id = match super::gate::random_key() {
        Ok(id) => id,
        Err(e) => {
            return ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response()
        }
    };
    lock(&edge.sessions).open(id.clone());
    (
        [(
            header::SET_COOKIE,
            format!("{}={id}; Path=/; HttpOnly; SameSite=Strict", edge.cookie),
        )],
        Redirect::to("/"),
    )
        .into_response()
}

/// Whether this page may act (no token needed, or it presented the right one or its
/// session), and the page key its actions carry: only a page of the console's own origin
/// can read this answer.
pub(super) async fn session(
    Extension(edge): Extension<Arc<Edge>>,
    headers: HeaderMap,
) -> Json<serde_json::Value> {
    let listen = edge.gate.listen();
    Json(serde_json::json!({
        "token_required": edge.token.is_some(),
        "authorised": authorised(&edge, &headers).is_ok(),
        "page_key": edge.gate.key(),
        "listen": listen.to_string(),
        "loopback": listen.ip().is_loopback(),
        "hosts": edge.gate.hosts(),
    }))
}

/// Every machine's lock and who holds it since when: this console's runs and a
/// `whirl stream` of another terminal alike.
async fn locks(State(console): State<Arc<Console>>) -> Json<Vec<super::runner::LockView>> {
    Json(console.locks())
}

async fn machines(State(console): State<Arc<Console>>) -> Json<Vec<String>> {
    Json(console.machines.keys().cloned().collect())
}

async fn jobs(State(console): State<Arc<Console>>) -> Json<Vec<String>> {
    Json(console.jobs.list())
}

#[derive(serde::Deserialize)]
struct JobOnly {
    job: String,
}

/// What whirl understood of a job's groove: a read, open as the job list is.
async fn profile(
    State(console): State<Arc<Console>>,
    Query(request): Query<JobOnly>,
) -> Result<Json<serde_json::Value>, ApiError> {
    blocking(move || console.profile(&request.job))
        .await
        .map(Json)
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
    Extension(client): Extension<Client>,
    Json(mut request): Json<RunRequest>,
) -> Result<Json<serde_json::Value>, ApiError> {
    request.client = client.0;
    let id = blocking(move || console.start(&request)).await?;
    Ok(Json(serde_json::json!({ "id": id })))
}

/// Hold, resume, stop, or resume a stopped run where it stopped (`resume-at`).
async fn press(
    State(console): State<Arc<Console>>,
    Extension(client): Extension<Client>,
    Path((machine, button)): Path<(String, String)>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let command = match button.as_str() {
        "hold" => Command::Hold,
        "resume" => Command::Resume,
        "stop" => Command::Stop {
            reason: "the console's stop button",
        },
        "resume-at" => {
            let id = blocking(move || console.resume(&machine, &client.0)).await?;
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
        if let Err(error) = console.note_pressed(&machine, kind, &client.0).await {
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
/// change, at most one event per [`EVENT_GAP`]; when the console ends, a `gone` event, and
/// the stream ends.
async fn events(
    State(console): State<Arc<Console>>,
    Extension(edge): Extension<Arc<Edge>>,
) -> Sse<impl futures_util::Stream<Item = Result<Event, Infallible>>> {
    let changes = console.registry.subscribe();
    let closing = edge.closing.subscribe();
    let stream = futures_util::stream::unfold(
        Some((console, changes, closing, true)),
        |state| async move {
            let (console, mut changes, mut closing, first) = state?;
            if !first {
                let gone = tokio::select! {
                    changed = changes.changed() => changed.is_err(),
                    _ = closing.wait_for(|&ended| ended) => true,
                };
                if gone {
                    let word = "whirl serve has ended after stopping its runs";
                    return Some((Ok(Event::default().event("gone").data(word)), None));
                }
                tokio::time::sleep(EVENT_GAP).await;
            }
            changes.borrow_and_update();
            let views =
                serde_json::to_string(&console.registry.views()).expect("run views serialise");
            Some((
                Ok(Event::default().event("runs").data(views)),
                Some((console, changes, closing, false)),
            ))
        },
    );
    Sse::new(stream).keep_alive(KeepAlive::default())
}
