-- The participation store (comments, likes, reports, viewpoints, meetings), one portable DDL
-- for SQLite and PostgreSQL: ids are assigned by the server (BIGINT), times are milliseconds
-- since the Unix epoch (BIGINT), JSON is kept as TEXT, coordinates as DOUBLE PRECISION.

CREATE TABLE comments (
    id BIGINT PRIMARY KEY,
    number BIGINT NOT NULL UNIQUE,
    x DOUBLE PRECISION NOT NULL,
    y DOUBLE PRECISION NOT NULL,
    z DOUBLE PRECISION NOT NULL,
    lon DOUBLE PRECISION NOT NULL,
    lat DOUBLE PRECISION NOT NULL,
    hit_kind TEXT NOT NULL,
    hit_layer TEXT,
    hit_plant BIGINT,
    camera TEXT NOT NULL,
    body TEXT NOT NULL,
    category TEXT,
    created_ms BIGINT NOT NULL,
    author TEXT NOT NULL,
    status TEXT NOT NULL,
    reports BIGINT NOT NULL DEFAULT 0
);

CREATE INDEX comments_created ON comments (created_ms);

CREATE TABLE likes (
    comment_id BIGINT NOT NULL REFERENCES comments (id),
    author TEXT NOT NULL,
    created_ms BIGINT NOT NULL,
    PRIMARY KEY (comment_id, author)
);

CREATE TABLE reports (
    comment_id BIGINT NOT NULL REFERENCES comments (id),
    author TEXT NOT NULL,
    created_ms BIGINT NOT NULL,
    PRIMARY KEY (comment_id, author)
);

CREATE TABLE viewpoints (
    name TEXT PRIMARY KEY,
    body TEXT NOT NULL,
    ordinal BIGINT NOT NULL,
    updated_ms BIGINT NOT NULL
);

CREATE TABLE meetings (
    code TEXT PRIMARY KEY,
    presenter TEXT NOT NULL,
    created_ms BIGINT NOT NULL,
    closed_ms BIGINT
);

-- Counters that only grow (pin numbers are never reused, even after a deletion).
CREATE TABLE counters (
    name TEXT PRIMARY KEY,
    value BIGINT NOT NULL
);

INSERT INTO counters (name, value) VALUES ('comment_number', 0);
