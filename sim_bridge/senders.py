"""What the bridge calls one *sender*, and the pages of a multiplexed message.

Pure naming. A sender is one stream of frames at its message's cycle time:

- a message (``LEG_SB1_F1``);
- a J1939 message mapped to several source addresses sends once per address
  (``HYD_PRESS@0x21``: one transducer per chamber);
- a multiplexed message sends once per **page**, each multiplexer value its DBC signals
  use (``MUXHUB#1``: the frame whose multiplexer says 1, with that page's signals).

Only simple multiplexing has pages: one multiplexer signal, itself not multiplexed.
Nested multiplexing (a multiplexer under another's value) has none the bridge can play.

>>> sender_name("HYD_PRESS", 0x21), sender_name("MUXHUB", None, 1)
('HYD_PRESS@0x21', 'MUXHUB#1')
>>> message_of("HYD_PRESS@0x21"), message_of("MUXHUB#1"), message_of("LEG_SB1_F1")
('HYD_PRESS', 'MUXHUB', 'LEG_SB1_F1')
"""

from cantools.database.can import Message, Signal

#: The pages of a message that is not multiplexed: one, without a multiplexer value.
UNPAGED: tuple[int | None, ...] = (None,)


def sender_name(message: str, source_address: int | None, page: int | None = None) -> str:
    """The name of one sender: the message, ``@0x21`` for a J1939 transducer, ``#1`` for
    the page of multiplexer value 1 (DBC names are identifiers: neither mark is in one)."""
    name = message if source_address is None else f"{message}@0x{source_address:02X}"
    return name if page is None else f"{name}#{page}"


def message_of(sender: str) -> str:
    """The DBC message a sender sends."""
    return sender.partition("@")[0].partition("#")[0]


def multiplexer_pages(message: Message) -> tuple[int | None, ...] | None:
    """The multiplexer values ``message``'s signals are sent under, in value order;
    :data:`UNPAGED` if it is not multiplexed; None for nested multiplexing."""
    if not message.is_multiplexed():
        return UNPAGED
    multiplexers = [signal for signal in message.signals if signal.is_multiplexer]
    if len(multiplexers) != 1 or multiplexers[0].multiplexer_ids:
        return None
    return tuple(sorted({page for s in message.signals for page in s.multiplexer_ids or ()}))


def on_page(signal: Signal, page: int | None) -> bool:
    """The frames of ``page`` (None: every frame) carry ``signal``."""
    return page is None or not signal.multiplexer_ids or page in signal.multiplexer_ids
