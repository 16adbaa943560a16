//! The history page's API: every run in the run records ([`crate::records`]), the
//! command line's and the console's alike, of every machine and host that records into
//! them (a shop's PostgreSQL holds every bridge's), searched by job, machine, host, date
//! and outcome in the database (the records' own filter, as `whirl runs list` searches),
//! and one run's whole record, as `whirl runs show` gives it.

use super::http::ApiError;
use super::runner::Console;
use crate::records::{Filter, Outcome, RunId, Timestamp};
use axum::extract::{Path, Query, State};
use axum::http::StatusCode;
use axum::Json;
use std::sync::Arc;

/// The most runs one search lists unless it asks for fewer: a page, not the shop's
/// whole history at once.
pub const LIST_LIMIT: u32 = 200;

/// A search as the page sends it (`/api/history?job=…&outcome=…`); empty fields are no
/// condition.
#[derive(Debug, Default, serde::Deserialize)]
pub struct Search {
    /// The job file's path or the program's name contains this (any case).
    pub job: Option<String>,
    /// The machine's name or profile file contains this (any case).
    pub machine: Option<String>,
    /// The host it ran on contains this (any case).
    pub host: Option<String>,
    /// Started at or after this UTC date or time.
    pub since: Option<String>,
    /// Started before this UTC date or time.
    pub until: Option<String>,
    /// Ended so: running, completed, stopped, failed or interrupted.
    pub outcome: Option<String>,
    /// At most this many, the newest (1 to [`LIST_LIMIT`]).
    pub limit: Option<String>,
}

/// The records' filter of `search`, or what is wrong with it, naming the field.
pub fn filter(search: &Search) -> Result<Filter, String> {
    let given = |field: &Option<String>| {
        field
            .as_deref()
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(str::to_owned)
    };
    let time = |name: &str, field: &Option<String>| {
        given(field)
            .map(|text| Timestamp::parse(&text).map_err(|e| format!("{name} \"{text}\": {e}")))
            .transpose()
    };
    let outcome = given(&search.outcome)
        .map(|word| {
            Outcome::from_word(&word).ok_or_else(|| {
                format!(
                    "outcome \"{word}\": must be running, completed, stopped, failed or \
                     interrupted"
                )
            })
        })
        .transpose()?;
    let limit = match given(&search.limit) {
        None => LIST_LIMIT,
        Some(text) => text
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=LIST_LIMIT).contains(n))
            .ok_or_else(|| {
                format!("limit \"{text}\": must be a whole number, 1 to {LIST_LIMIT}")
            })?,
    };
    Ok(Filter {
        job: given(&search.job),
        machine: given(&search.machine),
        since: time("since", &search.since)?,
        until: time("until", &search.until)?,
        outcome,
        host: given(&search.host),
        limit: Some(limit),
    })
}

fn records(console: &Console) -> Result<&crate::records::Store, ApiError> {
    console.records.as_ref().map(|r| &r.store).ok_or_else(|| {
        ApiError(
            StatusCode::SERVICE_UNAVAILABLE,
            "this console keeps no run records: it was started with --allow-unrecorded and \
             could not open the database"
                .into(),
        )
    })
}

/// `GET /api/history?…`: the runs the search lets through, newest first.
pub(super) async fn list(
    State(console): State<Arc<Console>>,
    Query(search): Query<Search>,
) -> Result<Json<Vec<crate::records::RunSummary>>, ApiError> {
    let filter = filter(&search).map_err(|e| ApiError(StatusCode::BAD_REQUEST, e))?;
    let store = records(&console)?;
    store
        .list(&filter)
        .await
        .map(Json)
        .map_err(|e| ApiError(StatusCode::SERVICE_UNAVAILABLE, e.to_string()))
}

/// `GET /api/history/{id}`: one run's whole record.
pub(super) async fn show(
    State(console): State<Arc<Console>>,
    Path(id): Path<RunId>,
) -> Result<Json<crate::records::Run>, ApiError> {
    let store = records(&console)?;
    match store.show(id).await {
        Ok(Some(run)) => Ok(Json(run)),
        Ok(None) => Err(ApiError(
            StatusCode::NOT_FOUND,
            format!("{} holds no run {id}", store.place()),
        )),
        Err(e) => Err(ApiError(StatusCode::SERVICE_UNAVAILABLE, e.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn search(pairs: &[(&str, &str)]) -> Search {
        let mut search = Search::default();
        for &(key, value) in pairs {
            let field = match key {
                "job" => &mut search.job,
                "machine" => &mut search.machine,
                "host" => &mut search.host,
                "since" => &mut search.since,
                "until" => &mut search.until,
                "outcome" => &mut search.outcome,
                _ => &mut search.limit,
            };
            *field = Some(value.to_owned());
        }
        search
    }

    #[test]
    fn a_search_becomes_the_records_filter_and_empty_fields_are_no_condition() {
        let f = filter(&search(&[
            ("job", "trapezoidal"),
            ("machine", " "),
            ("host", "Lathe-2"),
            ("since", "2026-05-01"),
            ("until", ""),
            ("outcome", "stopped"),
        ]))
        .unwrap();
        assert_eq!(f.job.as_deref(), Some("trapezoidal"));
        assert_eq!(f.machine, None);
        assert_eq!(f.host.as_deref(), Some("Lathe-2"));
        assert_eq!(f.since, Some(Timestamp::parse("2026-05-01").unwrap()));
        assert_eq!(f.until, None);
        assert_eq!(f.outcome, Some(Outcome::Stopped));
        assert_eq!(f.limit, Some(LIST_LIMIT));
        assert_eq!(filter(&Search::default()).unwrap().job, None);
    }

    #[test]
    fn a_bad_search_is_refused_naming_its_field() {
        let refused = |k, v| filter(&search(&[(k, v)])).unwrap_err();
        assert!(refused("outcome", "done").starts_with("outcome \"done\": must be running"));
        assert!(refused("since", "yesterday").starts_with("since \"yesterday\""));
        assert!(refused("until", "2026-13-01").starts_with("until \"2026-13-01\""));
        assert!(refused("limit", "0").starts_with("limit \"0\""));
        assert!(refused("limit", "201").starts_with("limit \"201\""));
        assert!(refused("limit", "x").starts_with("limit \"x\""));
    }
}
