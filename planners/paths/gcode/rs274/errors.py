"""The interpreter's one error: the file, the line (1-based) and what construct failed."""


class RS274Error(ValueError):
    def __init__(self, file: str, line: int, message: str):
        super().__init__(f"{file}:{line}: {message}")
        self.file, self.line, self.message = file, line, message


class LineError(Exception):
    """Raised inside one line's reading/evaluation; the interpreter adds file and line."""
