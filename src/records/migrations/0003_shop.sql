-- Run records, version 3 (docs/records.md): one database for a whole shop's bridges.
--
-- Every run and every note gets a key (128 random bits in hex), the same in every database
-- it is written to: a run kept in a bridge's spool while the shop's database could not be
-- reached is uploaded by its key, once, however often the upload is tried. Records made
-- before this version have none.
--
-- Run numbers come from a counter row that each new run takes in turn (both databases make
-- a writer wait while another holds the row), no longer from the largest number plus one,
-- which two bridges beginning at once both took.
ALTER TABLE runs ADD COLUMN uid TEXT;
CREATE UNIQUE INDEX runs_by_uid ON runs (uid);
ALTER TABLE run_notes ADD COLUMN uid TEXT;
CREATE UNIQUE INDEX run_notes_by_uid ON run_notes (uid);
CREATE TABLE counters (name TEXT PRIMARY KEY, last BIGINT NOT NULL);
INSERT INTO counters (name, last) SELECT 'runs', COALESCE(MAX(id), 0) FROM runs;
