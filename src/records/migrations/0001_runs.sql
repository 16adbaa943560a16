-- Run records, version 1 (docs/records.md). SQL that SQLite and PostgreSQL both accept:
-- whole numbers BIGINT, measurements DOUBLE PRECISION, everything else TEXT (times as UTC
-- RFC 3339 text of one width, which sorts as time does; reports as JSON text). Ids are
-- given by the store (the largest plus one), as the two databases share no way of making
-- them.

-- One row a run of whirl: opened `running` before anything is sent, closed with its outcome.
CREATE TABLE runs (
    id BIGINT PRIMARY KEY,
    kind TEXT NOT NULL,
    outcome TEXT NOT NULL,
    reason TEXT,
    started_at TEXT NOT NULL,
    ended_at TEXT,
    host TEXT NOT NULL,
    pid BIGINT NOT NULL,
    process_started BIGINT,
    boot_id TEXT,
    job_path TEXT,
    job_sha256 TEXT,
    job_text TEXT,
    machine_name TEXT,
    machine_path TEXT,
    machine_sha256 TEXT,
    machine_text TEXT,
    program_name TEXT,
    program_sha256 TEXT,
    program_lines BIGINT,
    transport TEXT,
    port TEXT,
    plan_report TEXT,
    max_overcut_mm DOUBLE PRECISION,
    max_undercut_mm DOUBLE PRECISION,
    delta_mm DOUBLE PRECISION,
    within_delta BIGINT,
    resume_from BIGINT,
    resumes BIGINT REFERENCES runs (id),
    resume_at BIGINT,
    possibly_run_to BIGINT,
    last_line BIGINT,
    log_path TEXT,
    log_offset BIGINT
);

CREATE INDEX runs_by_start ON runs (started_at);
CREATE INDEX runs_by_outcome ON runs (outcome, host);
CREATE INDEX runs_by_program ON runs (program_sha256);

-- What happened to a run as it went, in order: alarms, holds, resumes and its stop, each
-- with the program line it concerns.
CREATE TABLE run_notes (
    run_id BIGINT NOT NULL REFERENCES runs (id),
    seq BIGINT NOT NULL,
    at TEXT NOT NULL,
    kind TEXT NOT NULL,
    line BIGINT,
    code BIGINT,
    text TEXT NOT NULL,
    PRIMARY KEY (run_id, seq)
);
