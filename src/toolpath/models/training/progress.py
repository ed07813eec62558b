"""A rich progress bar over epochs showing loss and accuracy."""

from __future__ import annotations

from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from toolpath.models.training.loop import EpochRecord


class EpochBar:
    """Context manager; pass :meth:`update` as the training loop's ``on_epoch`` callback."""

    def __init__(self, label: str, epochs: int) -> None:
        self.label, self.epochs = label, epochs
        self.progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                 TimeElapsedColumn(), TextColumn("{task.fields[stats]}"))

    def __enter__(self) -> EpochBar:
        self.progress.__enter__()
        self.task = self.progress.add_task(f"train {self.label}", total=self.epochs, stats="")
        return self

    def update(self, record: EpochRecord) -> None:
        stats = (f"loss {record.train_loss:.3f} acc {record.train_accuracy:.3f} | "
                 f"val loss {record.val_loss:.3f} acc {record.val_accuracy:.3f}")
        self.progress.update(self.task, advance=1, stats=stats)

    def __exit__(self, *exc) -> None:
        self.progress.__exit__(*exc)
