-- Run records, version 2 (docs/records.md): what a run's program was planned from (its
-- provenance header, or the plan's own) and how that was checked, as JSON text.
ALTER TABLE runs ADD COLUMN provenance TEXT;
