"""Error types shown to users.

`UserInputError` is a `ValueError` whose message is complete on its own (it
names the file, column and row where they apply); the CLI prints it without a
traceback and exits with code 2.
"""


class UserInputError(ValueError):
    """Bad input from the user: a file, a column, a setting or a value."""


class DataError(UserInputError):
    """A data file that cannot be used as it is."""

    def __init__(self, path, message, *, column=None, row=None):
        where = str(path)
        if column is not None:
            where += f", column '{column}'"
        if row is not None:
            where += f", row {row}"
        super().__init__(f"{where}: {message}")
        self.path = path
        self.column = column
        self.row = row
